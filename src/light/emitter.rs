//! The direct light of one emitting triangle at a point (placeholder, filled below).
