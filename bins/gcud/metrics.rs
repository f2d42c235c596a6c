//! The optional Prometheus endpoint (`[metrics] listen`, loopback by
//! default): `GET /metrics` in the OpenMetrics text format, encoded by
//! `prometheus-client` from a snapshot of the router core's statistics,
//! `/status` and `/healthz`. Module `http` serves them (who may connect,
//! how many, for how long).

use std::fmt;

use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric};
use prometheus_client::metrics::MetricType;
use prometheus_client::metrics::counter::ConstCounter;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::registry::Registry;
use tokio::sync::{mpsc, oneshot};

/// Counter or gauge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Counter,
    Gauge,
}

/// A sample's value: a count, or a measurement (degrees, seconds since the
/// Unix epoch) that needs a fraction or a sign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    Count(u64),
    Real(f64),
}

/// One labelled value.
#[derive(Debug, Clone)]
pub struct Sample {
    pub labels: Vec<(&'static str, String)>,
    pub value: Value,
}

/// One metric family.
#[derive(Debug, Clone)]
pub struct Family {
    pub name: String,
    pub help: &'static str,
    pub kind: Kind,
    pub samples: Vec<Sample>,
}

impl Family {
    pub fn new(name: impl Into<String>, help: &'static str, kind: Kind) -> Self {
        Self {
            name: name.into(),
            help,
            kind,
            samples: Vec::new(),
        }
    }

    pub fn push(&mut self, labels: Vec<(&'static str, String)>, value: u64) {
        self.samples.push(Sample {
            labels,
            value: Value::Count(value),
        });
    }

    /// A gauge's measurement with a fraction or a sign.
    pub fn push_real(&mut self, labels: Vec<(&'static str, String)>, value: f64) {
        self.samples.push(Sample {
            labels,
            value: Value::Real(value),
        });
    }
}

/// A frozen set of families, encoded once.
#[derive(Debug)]
struct Snapshot(Vec<Family>);

impl Collector for Snapshot {
    fn encode(&self, mut encoder: DescriptorEncoder) -> Result<(), fmt::Error> {
        for family in &self.0 {
            let kind = match family.kind {
                Kind::Counter => MetricType::Counter,
                Kind::Gauge => MetricType::Gauge,
            };
            let mut metric = encoder.encode_descriptor(&family.name, family.help, None, kind)?;
            if let [Sample { labels, value }] = family.samples.as_slice()
                && labels.is_empty()
            {
                // A single unlabelled value: `name value`, not `name{} value`.
                encode_value(family.kind, *value, metric)?;
                continue;
            }
            for sample in &family.samples {
                encode_value(family.kind, sample.value, metric.encode_family(&sample.labels)?)?;
            }
        }
        Ok(())
    }
}

fn encode_value(
    kind: Kind,
    value: Value,
    encoder: prometheus_client::encoding::MetricEncoder<'_>,
) -> Result<(), fmt::Error> {
    match (kind, value) {
        (Kind::Counter, Value::Count(n)) => ConstCounter::new(n).encode(encoder),
        (Kind::Counter, Value::Real(x)) => ConstCounter::new(x).encode(encoder),
        (Kind::Gauge, Value::Count(n)) => ConstGauge::new(i64::try_from(n).unwrap_or(i64::MAX)).encode(encoder),
        (Kind::Gauge, Value::Real(x)) => ConstGauge::new(x).encode(encoder),
    }
}

/// Encodes `families` in the OpenMetrics text format.
pub fn render(families: Vec<Family>) -> String {
    let mut registry = Registry::with_prefix("gcud");
    registry.register_collector(Box::new(Snapshot(families)));
    let mut text = String::new();
    if prometheus_client::encoding::text::encode(&mut text, &registry).is_err() {
        text = "# gcud: metrics encoding failed\n".to_owned();
    }
    text
}

/// A scrape asks the router task for a fresh snapshot through this channel.
pub type ScrapeRequests = mpsc::Sender<oneshot::Sender<crate::stats::Snapshot>>;

/// How long `/healthz` waits for the router task before calling it stuck.
const HEALTH_WAIT: std::time::Duration = std::time::Duration::from_secs(1);

/// What the HTTP handlers share.
#[derive(Clone, Debug)]
struct Endpoint {
    scrapes: ScrapeRequests,
    http: std::sync::Arc<crate::http::Counters>,
}

impl Endpoint {
    /// A snapshot copied on the router task (counters only), or `None` if
    /// the task is gone. Rendering happens off that task, so that a scrape
    /// never stalls routing.
    async fn snapshot(&self) -> Option<crate::stats::Snapshot> {
        let (tx, rx) = oneshot::channel();
        self.scrapes.send(tx).await.ok()?;
        let mut snapshot = rx.await.ok()?;
        snapshot.http = self.http.stats();
        Some(snapshot)
    }
}

/// The pages, for module `http` to serve (to `[metrics] allow_peers`
/// only): `GET /metrics` (OpenMetrics text), `GET /status` (JSON, module
/// `status`) and `GET /healthz` (200 `ok` while the router task answers
/// within a second and gcud is not shutting down, 503 and why otherwise).
pub fn app(scrapes: ScrapeRequests, http: std::sync::Arc<crate::http::Counters>) -> axum::Router {
    use axum::extract::State;
    use axum::http::StatusCode;
    use axum::response::{IntoResponse, Response};
    use axum::routing::get;

    async fn metrics(State(endpoint): State<Endpoint>) -> Response {
        let body = match endpoint.snapshot().await {
            Some(s) => tokio::task::spawn_blocking(move || crate::stats::render(&s))
                .await
                .unwrap_or_default(),
            None => String::new(),
        };
        (
            [(
                "content-type",
                "application/openmetrics-text; version=1.0.0; charset=utf-8",
            )],
            body,
        )
            .into_response()
    }

    async fn status(State(endpoint): State<Endpoint>) -> Response {
        match endpoint.snapshot().await {
            Some(s) => axum::Json(crate::status::Status::of(&s)).into_response(),
            None => (StatusCode::SERVICE_UNAVAILABLE, "gcud is stopping\n").into_response(),
        }
    }

    async fn healthz(State(endpoint): State<Endpoint>) -> Response {
        match tokio::time::timeout(HEALTH_WAIT, endpoint.snapshot()).await {
            Ok(Some(s)) if s.shutting_down => (StatusCode::SERVICE_UNAVAILABLE, "shutting down\n").into_response(),
            Ok(Some(_)) => (StatusCode::OK, "ok\n").into_response(),
            Ok(None) => (StatusCode::SERVICE_UNAVAILABLE, "gcud is stopping\n").into_response(),
            Err(_) => (
                StatusCode::SERVICE_UNAVAILABLE,
                "router task did not answer within 1 s\n",
            )
                .into_response(),
        }
    }

    axum::Router::new()
        .route("/metrics", get(metrics))
        .route("/status", get(status))
        .route("/healthz", get(healthz))
        .with_state(Endpoint { scrapes, http })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_counters_and_gauges_with_labels() {
        let mut frames = Family::new("port_frames_out", "Frames written to a port.", Kind::Counter);
        frames.push(vec![("port", "1".to_owned())], 7);
        let mut up = Family::new("port_up", "Whether the port is open.", Kind::Gauge);
        up.push(vec![("port", "1".to_owned())], 1);
        let text = render(vec![frames, up]);
        assert!(text.contains("# TYPE gcud_port_frames_out counter"), "{text}");
        assert!(text.contains("gcud_port_frames_out_total{port=\"1\"} 7"), "{text}");
        assert!(text.contains("gcud_port_up{port=\"1\"} 1"), "{text}");
        assert!(text.ends_with("# EOF\n"), "{text}");
    }
}
