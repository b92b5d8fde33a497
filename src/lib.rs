//! radiosity
