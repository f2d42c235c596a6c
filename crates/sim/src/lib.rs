//! Gimbal simulator model (placeholder until issue 3 lands).
