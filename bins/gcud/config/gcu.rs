//! `[gcu]`: this GCU (Table 2 group, Table 6 identity, shutdown grace).

use sagebrush_service::config_file::{Int, Millis, checked};
use serde::{Deserialize, Deserializer, Serialize};
use toml::Spanned;

/// `[gcu]`, as written and as validated.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GcuSection {
    /// Group address 1..=254 (Table 2).
    pub group: Int<u8, 1, 254>,
    /// Device name for `D?` (Table 6).
    #[serde(default = "Text20::gcud")]
    pub name: Text20,
    /// Serial number for `D?` (Table 6).
    #[serde(default)]
    pub serial: Text20,
    /// Link name that frames for unknown groups go to: checked, and
    /// compared by a reload, with the routes (module `route`).
    #[serde(skip_serializing)]
    pub default_route: Option<Spanned<String>>,
    /// On SIGTERM: how long in-flight transactions may take to finish;
    /// 0 (stop at once) to 10 minutes.
    #[serde(default)]
    pub shutdown_grace_ms: Millis<0, 600_000, 3000>,
    /// Threads of the ports' I/O, the router task's counted (module
    /// `shard`): 1 runs every line on the router task's thread.
    #[serde(default)]
    pub threads: Int<u8, 1, 64, 1>,
}

/// At most 20 printable ASCII characters, trailing spaces dropped (Table 6).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
#[serde(transparent)]
pub struct Text20(String);

impl Text20 {
    fn gcud() -> Self {
        Self("gcud".to_owned())
    }

    pub fn get(&self) -> &str {
        &self.0
    }
}

impl<'de> Deserialize<'de> for Text20 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (text, _) = checked(d, |s: &String| {
            if s.len() > 20 || !s.bytes().all(|b| (0x20..=0x7E).contains(&b)) {
                return Err("expected at most 20 printable ASCII characters (Table 6)".to_owned());
            }
            Ok(s.trim_end().to_owned())
        })?;
        Ok(Self(text))
    }
}
