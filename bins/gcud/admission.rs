//! Who may hold an accepted connection: the bounded listener's admission
//! table (crate `sagebrush-service`, module `admission`), which every
//! LAN-facing socket of the project shares: a total cap evicting the
//! longest-idle holder, a per-peer cap, an idle time-out, rate-limited
//! refusal logs and the counters of gcud's metrics.

pub use sagebrush_service::admission::{AdmissionStats, Admitted, Connections, Ending, Limits};
