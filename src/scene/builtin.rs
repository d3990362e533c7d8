//! Built-in procedural scenes.
