//! `[log]`: the tracing filter.

use sagebrush_service::config_file::checked;
use serde::{Deserialize, Deserializer, Serialize};

/// `[log]`, as written and as validated.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LogSection {
    /// A tracing filter (`info`, `debug`, `gcud=debug,info`); `RUST_LOG` wins.
    pub level: Option<LogFilter>,
}

impl LogSection {
    /// The filter logging starts with: `level`, or `info`.
    pub fn filter(&self) -> &str {
        self.level.as_ref().map_or("info", |l| l.0.as_str())
    }
}

/// A tracing filter that names levels, or targets that cannot be misspelt
/// levels ([`check_log_filter`]), and that `tracing` accepts.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(transparent)]
pub struct LogFilter(String);

impl<'de> Deserialize<'de> for LogFilter {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (filter, _) = checked(d, |level: &String| {
            check_log_filter(level)?;
            sagebrush_host::logging::check_filter(level)
                .map_err(|e| format!("expected a level or tracing filter like \"info\": {e}"))?;
            Ok(level.clone())
        })?;
        Ok(Self(filter))
    }
}

/// The levels a `log.level` directive may name (any case).
const LOG_LEVELS: [&str; 6] = ["error", "warn", "info", "debug", "trace", "off"];

/// Catches what `EnvFilter` accepts but almost certainly is a mistake: it
/// reads a misspelt level such as `wran` as a *target* name, which enables
/// that (non-existent) target and so silences all logging.
///
/// The rule, per comma-separated directive (empty ones are ignored, as
/// `EnvFilter` does, but there must be at least one):
/// - with a `=` after any `[span]` part (`target=level`, `target[span]=level`,
///   `[span]=level`): the text after the `=` must be a level;
/// - without one: the directive is a level, or a span filter (contains `[`),
///   or a target that cannot be a misspelt level: a module path (contains
///   `::`) or a crate name with `_` such as `sagebrush_gcu`. A one-word
///   target such as `gcud` is written `gcud=trace`.
///
/// Levels are `error`, `warn`, `info`, `debug`, `trace` and `off`, in any
/// case (`EnvFilter`'s numeric levels `0`..`5` are refused: write the name).
fn check_log_filter(filter: &str) -> Result<(), String> {
    let expected = "expected a level (error, warn, info, debug, trace, off) \
                    or directives like \"gcud=debug,info\"";
    let is_level = |s: &str| LOG_LEVELS.iter().any(|l| s.trim().eq_ignore_ascii_case(l));
    if filter.split(',').all(|d| d.trim().is_empty()) {
        return Err(format!(
            "{expected}, found an empty filter (remove the key for the default, info)"
        ));
    }
    for directive in filter.split(',').map(str::trim).filter(|d| !d.is_empty()) {
        // The level follows the last `=` outside a `[span{field=value}]` part.
        let tail = directive.rfind(']').map_or(directive, |i| &directive[i + 1..]);
        match tail.rfind('=') {
            Some(i) => {
                let level = &tail[i + 1..];
                if !is_level(level) {
                    return Err(format!("{expected}, found level {level:?} in directive {directive:?}"));
                }
            }
            None => {
                let target_only = directive.contains("::") || directive.contains('_') || directive.contains('[');
                if !is_level(directive) && !target_only {
                    return Err(format!(
                        "{expected}, found {directive:?} (not a level; as a target name it would \
                         turn every other message off; write TARGET=LEVEL)"
                    ));
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_filters_name_levels_or_targets_that_cannot_be_misspelt_levels() {
        for ok in [
            "info",
            "WARN,gcud=debug",
            "sagebrush_gcu",
            "gcud::io=trace",
            "[conn]",
            "gcud[conn{peer=a}]=debug",
            "info,",
        ] {
            assert_eq!(check_log_filter(ok), Ok(()), "{ok:?}");
        }
        for bad in [
            "wran",
            "gcud",
            "info,gcud=wran",
            "gcud=",
            "gcud=3",
            "[conn]=x",
            "",
            " , ",
        ] {
            assert!(check_log_filter(bad).is_err(), "{bad:?}");
        }
    }
}
