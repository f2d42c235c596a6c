//! The optional Prometheus endpoint (`[metrics] listen`, loopback by
//! default): `GET /metrics` in the OpenMetrics text format, encoded by
//! `prometheus-client` from a snapshot of the router core's statistics.

use std::fmt;

use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric};
use prometheus_client::metrics::MetricType;
use prometheus_client::metrics::counter::ConstCounter;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::registry::Registry;
use tokio::net::TcpListener;
use tokio::sync::{mpsc, oneshot};

/// Counter or gauge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Counter,
    Gauge,
}

/// One labelled value.
#[derive(Debug, Clone)]
pub struct Sample {
    pub labels: Vec<(&'static str, String)>,
    pub value: u64,
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
        self.samples.push(Sample { labels, value });
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
    value: u64,
    encoder: prometheus_client::encoding::MetricEncoder<'_>,
) -> Result<(), fmt::Error> {
    match kind {
        Kind::Counter => ConstCounter::new(value).encode(encoder),
        Kind::Gauge => ConstGauge::new(i64::try_from(value).unwrap_or(i64::MAX)).encode(encoder),
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

/// A scrape asks the router task for fresh text through this channel.
pub type ScrapeRequests = mpsc::Sender<oneshot::Sender<crate::stats::Snapshot>>;

/// Serves `GET /metrics` until the process ends.
pub async fn serve(listener: TcpListener, allow_peers: crate::config::PeerAllowList, scrapes: ScrapeRequests) {
    use axum::extract::ConnectInfo;
    use axum::http::StatusCode;
    use axum::response::IntoResponse;
    let app = axum::Router::new().route(
        "/metrics",
        axum::routing::get(move |ConnectInfo(peer): ConnectInfo<std::net::SocketAddr>| {
            let scrapes = scrapes.clone();
            let allowed = allow_peers.contains(&peer.ip());
            async move {
                if !allowed {
                    return (StatusCode::FORBIDDEN, "not in [metrics] allow_peers\n").into_response();
                }
                // The router task only copies its counters; the text is
                // rendered here, so that a scrape never stalls routing.
                let (tx, rx) = oneshot::channel();
                let snapshot = match scrapes.send(tx).await {
                    Ok(()) => rx.await.ok(),
                    Err(_) => None,
                };
                let body = match snapshot {
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
        }),
    );
    let app = app.into_make_service_with_connect_info::<std::net::SocketAddr>();
    if let Err(e) = axum::serve(listener, app).await {
        tracing::error!(error = %e, "metrics endpoint stopped");
    }
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
