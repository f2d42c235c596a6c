//! What every service facing the LAN shares, gcud and its front doors
//! (gimbal-onvif, gimbal-mavlink, gimbal-web) alike, none of which needs
//! the master side of an exchange (`sagebrush-client`) for it:
//!
//! - [`config_file`]: TOML configuration read with bounds, every error at
//!   its file:line:column with its key and what was expected.
//! - [`door_config`]: the pieces every door with users shares: `[[user]]`,
//!   the preset state file, `[http]`.
//! - [`door_link`]: the keys at the top of every door's file (`gcud`,
//!   `gcud_tls`, `source_group`, `poll_ms`, `nic_window_ms`, `[metrics]`),
//!   read beside the door's own in one pass.
//! - [`door_metrics`]: a door's own metrics, `[metrics] listen`.
//! - [`door_tls`]: HTTPS at the doors, `[http] tls` (the site's
//!   certificate or a self-signed one the door makes and keeps).
//! - [`door`]: a front door's start-up (`--check`, exit codes, logging,
//!   runtime, its metrics and the signals that stop it).
//! - [`endpoint`]: the one parser of `HOST:PORT` and of `IP:PORT` to
//!   listen on, for configuration files and command lines alike.
//! - The bounded listener (ARCHITECTURE "Bounded and fair under load"):
//!   every socket that faces the LAN has a cap on connections (in all and
//!   per peer), header, body and idle time-outs, bounded buffers and
//!   rate-limited logging. gcud's client listeners admit through
//!   [`admission`]; the doors serve HTTP through [`http`]; [`rate`] holds
//!   the token buckets that bound what one user or one source may make a
//!   door spend.
//!
//! A door adopts the listener in three steps (what gimbal-mavlink's TCP
//! listener needs): one [`Connections`] table per program, a
//! [`BoundedListener`] per socket, and per accepted connection the
//! [`Admitted`] guard: its [`Admitted::track`]ed stream touches the entry
//! when bytes move, and [`Admitted::ended`] resolves when it must close
//! (evicted or idle).

pub mod admission;
pub mod config_file;
pub mod door;
pub mod door_config;
pub mod door_link;
pub mod door_metrics;
pub mod door_tls;
pub mod endpoint;
pub mod http;
pub mod rate;

pub use admission::{Admission, AdmissionStats, Admitted, Connections, Ending, Limits, Tracked};
pub use http::{BoundedListener, HttpLimits, Local, Peer, serve_http};
