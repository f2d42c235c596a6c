//! `[metrics]`: the HTTP endpoint (`/metrics`, `/status`, `/healthz`).

use std::net::SocketAddr;

use sagebrush_service::config_file::Source;
use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::net::{PeerAllowList, loopback, peers, socket};
use super::{Checks, ConfigError};

/// `[metrics]`, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MetricsSection {
    /// Address to serve on; loopback unless you mean otherwise.
    #[serde(default = "default_listen")]
    listen: Spanned<String>,
    /// Peer addresses allowed to scrape (default: loopback only).
    allow_peers: Option<Spanned<Vec<Spanned<String>>>>,
}

fn default_listen() -> Spanned<String> {
    Spanned::new(0..0, "127.0.0.1:9187".to_owned())
}

/// `[metrics]`, validated.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Metrics {
    pub listen: SocketAddr,
    /// Peers allowed to scrape.
    pub allow_peers: PeerAllowList,
}

impl MetricsSection {
    pub(super) fn validate(&self, c: &Source<'_>, checks: &mut Checks) -> Result<Metrics, ConfigError> {
        let listen = socket(c, &self.listen, "metrics.listen")?;
        let allow_peers = match &self.allow_peers {
            Some(list) => peers(c, list, "metrics.allow_peers")?,
            None => loopback(),
        };
        let place = checks.listener(c, listen, self.listen.span(), "metrics.listen");
        if !listen.ip().is_loopback() {
            checks.warnings.push(format!(
                "{place}: serves /metrics on {listen}, not on loopback: reachable from other machines \
                 (allow_peers: {allow_peers})"
            ));
        }
        Ok(Metrics { listen, allow_peers })
    }
}
