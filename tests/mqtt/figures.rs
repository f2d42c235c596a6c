//! Figures for the closing note (written next).
