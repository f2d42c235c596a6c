//! Router core (placeholder until issue 4 lands).
