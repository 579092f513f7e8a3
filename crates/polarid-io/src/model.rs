//! Trained classification models (JSON) (to be written).
