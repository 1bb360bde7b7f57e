//! The operator's line protocol (grbl 1.1 style), the loader task's work.
pub mod settings;
