//! What an experiment describes.
