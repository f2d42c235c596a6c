//! A door's own metrics (ARCHITECTURE "Front doors"), opt-in:
//! `[metrics] listen = "127.0.0.1:PORT"` serves `GET /metrics` in the
//! OpenMetrics text format, written by `prometheus-client`, on a bounded
//! listener of its own (a scraper on the LAN does not share the users'
//! connection cap). Every door exports, under `sagebrush_door_`:
//! `requests_total{door,kind}` (what its clients asked: an HTTP API
//! action, a SOAP operation, a MAVLink command, a VISCA or Pelco command),
//! `sessions{door}` (its clients live now: signed-in pages' event streams,
//! ground stations, connections), and the families the door adds
//! ([`CountFamily`]: `sagebrush-client`'s bus outcomes and gcud's
//! refusals by reason, read at each scrape).

use std::convert::Infallible;
use std::fmt;
use std::future::Future;
use std::net::SocketAddr;
use std::sync::{Arc, OnceLock};

use http_body_util::Full;
use hyper::body::Bytes;
use hyper::{Request, Response, StatusCode};
use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeLabelSet, EncodeMetric};
use prometheus_client::metrics::counter::{ConstCounter, Counter};
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::registry::Registry;
use serde::Deserialize;
use toml::Spanned;
use tracing::info;

use crate::config_file::{ConfigError, Source};
use crate::{BoundedListener, HttpLimits, Limits};

/// `[metrics]`, as written: where the door's metrics listen (absent: none).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetricsSection {
    listen: Spanned<String>,
}

impl Source<'_> {
    /// `[metrics] listen`: the address of the door's metrics listener.
    pub fn metrics_listen(&self, section: Option<&MetricsSection>) -> Result<Option<SocketAddr>, ConfigError> {
        section
            .map(|m| self.listen_address(&m.listen, "metrics.listen"))
            .transpose()
    }
}

/// Counts a door reads at each scrape, by one label: a counter family.
pub struct CountFamily {
    /// Its name under `sagebrush_door_` (the encoder adds `_total`).
    pub name: &'static str,
    pub help: &'static str,
    /// The label telling its counts apart.
    pub label: &'static str,
    /// The counts now, by label value.
    pub read: fn() -> Vec<(&'static str, u64)>,
}

impl fmt::Debug for CountFamily {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CountFamily")
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct RequestLabels {
    door: &'static str,
    kind: String,
}

/// How many clients a door has live now, read at each scrape.
type SessionCount = Box<dyn Fn() -> usize + Send + Sync>;

/// A door's metrics: what it counts as it serves, and its registry.
pub struct DoorMetrics {
    door: &'static str,
    requests: Family<RequestLabels, Counter>,
    sessions: Arc<OnceLock<SessionCount>>,
    registry: Registry,
}

impl fmt::Debug for DoorMetrics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("DoorMetrics")
            .field("door", &self.door)
            .finish_non_exhaustive()
    }
}

impl DoorMetrics {
    /// The metrics of door `door` (its program's name), with `families`.
    pub fn new(door: &'static str, families: Vec<CountFamily>) -> Arc<Self> {
        let mut registry = Registry::with_prefix("sagebrush_door");
        let requests = Family::<RequestLabels, Counter>::default();
        registry.register("requests", "What the door's clients asked, by kind.", requests.clone());
        let sessions = Arc::new(OnceLock::new());
        registry.register_collector(Box::new(Counts {
            door,
            families,
            sessions: Arc::clone(&sessions),
        }));
        Arc::new(Self {
            door,
            requests,
            sessions,
            registry,
        })
    }

    /// One request of `kind` from a client (a bounded set: the door's
    /// routes, operations or commands, never a client's own text).
    pub fn request(&self, kind: &str) {
        let labels = RequestLabels {
            door: self.door,
            kind: kind.to_owned(),
        };
        self.requests.get_or_create(&labels).inc();
    }

    /// Where the door's live clients are counted (read at each scrape;
    /// the first call counts, later ones are ignored; none: 0).
    pub fn count_sessions(&self, count: impl Fn() -> usize + Send + Sync + 'static) {
        let _ = self.sessions.set(Box::new(count));
    }

    /// The OpenMetrics text of a scrape.
    pub fn render(&self) -> String {
        let mut text = String::new();
        prometheus_client::encoding::text::encode(&mut text, &self.registry).expect("writing to a String cannot fail");
        text
    }

    /// The metrics of door `door` with `families`, served on `listen`
    /// when the configuration has `[metrics] listen` (a task of the
    /// runtime, for as long as it runs): an address that cannot be bound
    /// fails the start, naming it.
    pub async fn start(
        door: &'static str,
        families: Vec<CountFamily>,
        listen: Option<SocketAddr>,
    ) -> Result<Arc<Self>, String> {
        let metrics = Self::new(door, families);
        if let Some(listen) = listen {
            let serve = Arc::clone(&metrics)
                .bind(listen)
                .await
                .map_err(|e| format!("metrics.listen {listen}: cannot listen: {e}"))?;
            tokio::spawn(serve);
        }
        Ok(metrics)
    }

    /// Binds `listen` and returns the server of `GET /metrics` there (until
    /// dropped); logs where (`metrics at /metrics` with its address).
    pub async fn bind(self: Arc<Self>, listen: SocketAddr) -> std::io::Result<impl Future<Output = ()> + use<>> {
        let socket = tokio::net::TcpListener::bind(listen).await?;
        let local = socket.local_addr()?;
        info!(addr = %local, "metrics at /metrics");
        let table = crate::Connections::new(Limits {
            max_total: 16,
            max_per_peer: 4,
            cap_loopback: true,
            idle_timeout: std::time::Duration::from_secs(60),
        });
        let listener = BoundedListener::new(socket, table, "metrics");
        let service = tower::service_fn(move |request: Request<crate::http::RequestBody>| {
            let metrics = Arc::clone(&self);
            async move { Ok::<_, Infallible>(metrics.answer(request.uri().path())) }
        });
        Ok(crate::serve_http(listener, HttpLimits::default(), None, service))
    }

    fn answer(&self, path: &str) -> Response<Full<Bytes>> {
        let (status, kind, body) = match path {
            "/metrics" => (
                StatusCode::OK,
                "application/openmetrics-text; version=1.0.0; charset=utf-8",
                self.render(),
            ),
            _ => (
                StatusCode::NOT_FOUND,
                "text/plain; charset=utf-8",
                "only /metrics here\n".to_owned(),
            ),
        };
        Response::builder()
            .status(status)
            .header("content-type", kind)
            .body(Full::new(Bytes::from(body)))
            .expect("a valid response")
    }
}

/// The clients a door that serves datagrams heard lately, for its
/// sessions (UDP has no connection to count): at most `max`, the one
/// heard the longest ago forgotten first, so a flood of sources costs a
/// bounded table.
#[derive(Debug)]
pub struct HeardLately {
    at: std::sync::Mutex<std::collections::HashMap<SocketAddr, std::time::Instant>>,
    max: usize,
    within: std::time::Duration,
}

impl HeardLately {
    /// A client counts while heard within `within`; `max` kept at most.
    pub fn new(max: usize, within: std::time::Duration) -> Self {
        Self {
            at: std::sync::Mutex::default(),
            max,
            within,
        }
    }

    /// `from` was heard now.
    pub fn note(&self, from: SocketAddr) {
        let mut at = self.at.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if !at.contains_key(&from) && at.len() >= self.max {
            if let Some(oldest) = at.iter().min_by_key(|(_, t)| **t).map(|(a, _)| *a) {
                at.remove(&oldest);
            }
        }
        at.insert(from, std::time::Instant::now());
    }

    /// The clients heard within the window.
    pub fn live(&self) -> usize {
        let at = self.at.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        at.values().filter(|t| t.elapsed() < self.within).count()
    }
}

/// The sessions and the [`CountFamily`]s, read at each scrape.
struct Counts {
    door: &'static str,
    families: Vec<CountFamily>,
    sessions: Arc<OnceLock<SessionCount>>,
}

impl fmt::Debug for Counts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Counts")
            .field("families", &self.families)
            .finish_non_exhaustive()
    }
}

impl Collector for Counts {
    fn encode(&self, mut encoder: DescriptorEncoder<'_>) -> Result<(), fmt::Error> {
        let live = self.sessions.get().map_or(0, |count| count());
        let gauge = ConstGauge::new(i64::try_from(live).unwrap_or(i64::MAX));
        {
            let mut metric =
                encoder.encode_descriptor("sessions", "The door's clients live now.", None, gauge.metric_type())?;
            gauge.encode(metric.encode_family(&[("door", self.door)])?)?;
        }
        for family in &self.families {
            let mut metric = encoder.encode_descriptor(
                family.name,
                family.help,
                None,
                ConstCounter::<u64>::new(0).metric_type(),
            )?;
            for (value, n) in (family.read)() {
                let labels = [("door", self.door), (family.label, value)];
                ConstCounter::new(n).encode(metric.encode_family(&labels)?)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcomes() -> Vec<(&'static str, u64)> {
        vec![("delivered", 3), ("refused", 1)]
    }

    #[test]
    fn the_clients_heard_lately_are_bounded_and_age_out() {
        let heard = HeardLately::new(4, std::time::Duration::from_millis(200));
        for port in 0..100u16 {
            heard.note(SocketAddr::from(([127, 0, 0, 3], port)));
        }
        assert_eq!(heard.live(), 4);
        std::thread::sleep(std::time::Duration::from_millis(250));
        assert_eq!(heard.live(), 0);
    }

    #[test]
    fn a_scrape_has_requests_sessions_and_the_doors_families() {
        let m = DoorMetrics::new(
            "gimbal-test",
            vec![CountFamily {
                name: "bus_outcomes",
                help: "Commands by outcome.",
                label: "outcome",
                read: outcomes,
            }],
        );
        m.request("move");
        m.request("move");
        m.count_sessions(|| 1);
        let text = m.render();
        for want in [
            "sagebrush_door_requests_total{door=\"gimbal-test\",kind=\"move\"} 2",
            "sagebrush_door_sessions{door=\"gimbal-test\"} 1",
            "sagebrush_door_bus_outcomes_total{door=\"gimbal-test\",outcome=\"delivered\"} 3",
            "sagebrush_door_bus_outcomes_total{door=\"gimbal-test\",outcome=\"refused\"} 1",
            "# EOF",
        ] {
            assert!(text.contains(want), "{want} in:\n{text}");
        }
    }
}
