//! `[capture]`: pcapng capture of every port and link (docs/capture.md);
//! SIGUSR1 starts and stops it at run time.

use std::path::PathBuf;

use sagebrush_service::config_file::{Int, Source};
use serde::Deserialize;
use toml::Spanned;

use super::ConfigError;

const GIB: i64 = 1 << 30;
/// A size in bytes: 4 KiB (one block or two) to 1 TiB.
type Bytes = Int<u64, 4096, { 1024 * GIB }>;

/// `[capture]`, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CaptureSection {
    /// The pcapng file written (older ones rotate to NAME.1.pcapng, ...).
    file: Spanned<String>,
    /// Capture from start-up; SIGUSR1 toggles either way.
    #[serde(default = "yes")]
    enabled: bool,
    /// Start a new file past this size (default: one file).
    rotate_bytes: Option<Bytes>,
    /// Files kept, the current one included.
    #[serde(default)]
    rotate_count: Int<u32, 1, 1000, 4>,
    /// Stop capturing after this many bytes in all (default: no limit).
    budget_bytes: Option<Bytes>,
}

fn yes() -> bool {
    true
}

/// `[capture]`, validated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CaptureSettings {
    pub file: PathBuf,
    pub enabled: bool,
    pub rotate_bytes: Option<u64>,
    pub rotate_count: u32,
    pub budget_bytes: Option<u64>,
}

impl CaptureSection {
    pub(super) fn validate(&self, c: &Source<'_>) -> Result<CaptureSettings, ConfigError> {
        let file = self.file.get_ref().trim();
        if file.is_empty() {
            return Err(c.at(self.file.span(), "capture.file", "expected a file path"));
        }
        Ok(CaptureSettings {
            file: PathBuf::from(file),
            enabled: self.enabled,
            rotate_bytes: self.rotate_bytes.as_ref().map(Int::get),
            rotate_count: self.rotate_count.get(),
            budget_bytes: self.budget_bytes.as_ref().map(Int::get),
        })
    }
}

impl CaptureSettings {
    pub fn capture_config(&self) -> sagebrush_host::capture::CaptureConfig {
        sagebrush_host::capture::CaptureConfig {
            rotate_bytes: self.rotate_bytes,
            rotate_count: self.rotate_count,
            budget_bytes: self.budget_bytes,
            application: format!("gcud {}", env!("CARGO_PKG_VERSION")),
            ..Default::default()
        }
    }
}
