//! PNG views of DoLP and AoLP images (to be written).
