//! Classification CSV — written by `classify` (to be written).
