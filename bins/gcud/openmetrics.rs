//! The OpenMetrics text format (what `GET /metrics` answers), written by
//! `prometheus-client`'s text encoder: gcud hands it families of constant
//! samples, already read from a snapshot, through a [`Collector`], so the
//! format's rules (`# HELP`/`# TYPE`/`# UNIT`, a counter's `_total`, label
//! escaping, number formatting, `# EOF`) have the library as their one
//! home. A family is declared once, as a [`Descriptor`] (module
//! `metric_families` holds gcud's table of them).

use std::borrow::Cow;
use std::fmt;

use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric, MetricEncoder};
use prometheus_client::metrics::MetricType;
use prometheus_client::metrics::counter::ConstCounter;
use prometheus_client::metrics::gauge::ConstGauge;
use prometheus_client::registry::Registry;

/// Counter or gauge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Counter,
    Gauge,
}

/// A family's unit: the suffix of its name and its `# UNIT` line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    Seconds,
    Milliseconds,
    Bytes,
    Degrees,
}

impl Unit {
    fn encoded(self) -> prometheus_client::registry::Unit {
        use prometheus_client::registry::Unit as U;
        match self {
            Unit::Seconds => U::Seconds,
            Unit::Bytes => U::Bytes,
            Unit::Milliseconds => U::Other("ms".to_owned()),
            Unit::Degrees => U::Other("degrees".to_owned()),
        }
    }
}

/// A metric family as declared: its name (without the `gcud_` prefix nor
/// the unit, which the encoder appends), type, unit and help.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Descriptor {
    pub name: &'static str,
    pub kind: Kind,
    pub unit: Option<Unit>,
    pub help: &'static str,
}

impl Descriptor {
    pub const fn counter(name: &'static str, help: &'static str) -> Self {
        Self {
            name,
            kind: Kind::Counter,
            unit: None,
            help,
        }
    }

    pub const fn gauge(name: &'static str, help: &'static str) -> Self {
        Self {
            name,
            kind: Kind::Gauge,
            unit: None,
            help,
        }
    }

    /// The same family, measured in `unit`.
    pub const fn in_unit(self, unit: Unit) -> Self {
        Self {
            unit: Some(unit),
            ..self
        }
    }
}

/// A sample's value: a count, or a measurement (degrees, seconds since the
/// Unix epoch) that needs a fraction or a sign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    Count(u64),
    Real(f64),
}

/// A sample's labels, in the order they are written.
pub type Labels = Vec<(&'static str, String)>;

/// One family and its samples.
#[derive(Debug, Clone)]
pub struct Family {
    name: Cow<'static, str>,
    descriptor: Descriptor,
    samples: Vec<(Labels, Value)>,
}

impl Family {
    pub fn new(descriptor: Descriptor) -> Self {
        Self {
            name: Cow::Borrowed(descriptor.name),
            descriptor,
            samples: Vec::new(),
        }
    }

    /// A family of the same declaration under `scope` (`port` for
    /// `port_frames_in`): one declaration serves ports and links alike.
    pub fn scoped(scope: &str, descriptor: Descriptor) -> Self {
        Self {
            name: Cow::Owned(format!("{scope}_{}", descriptor.name)),
            ..Self::new(descriptor)
        }
    }

    pub fn push(&mut self, labels: Labels, value: Value) {
        self.samples.push((labels, value));
    }
}

/// Families of constant samples, handed to the encoder once.
#[derive(Debug)]
struct Constants {
    families: Vec<Family>,
}

impl Collector for Constants {
    fn encode(&self, mut encoder: DescriptorEncoder) -> Result<(), fmt::Error> {
        for family in &self.families {
            let Descriptor { kind, unit, help, .. } = family.descriptor;
            let unit = unit.map(Unit::encoded);
            let kind = match kind {
                Kind::Counter => MetricType::Counter,
                Kind::Gauge => MetricType::Gauge,
            };
            let mut metric = encoder.encode_descriptor(&family.name, help, unit.as_ref(), kind)?;
            if let [(labels, value)] = family.samples.as_slice()
                && labels.is_empty()
            {
                // A single unlabelled value: `name value`, not `name{} value`.
                encode_value(kind, *value, metric)?;
                continue;
            }
            for (labels, value) in &family.samples {
                encode_value(kind, *value, metric.encode_family(labels)?)?;
            }
        }
        Ok(())
    }
}

fn encode_value(kind: MetricType, value: Value, encoder: MetricEncoder<'_>) -> Result<(), fmt::Error> {
    match (kind, value) {
        (MetricType::Counter, Value::Count(n)) => ConstCounter::new(n).encode(encoder),
        (MetricType::Counter, Value::Real(x)) => ConstCounter::new(x).encode(encoder),
        (_, Value::Count(n)) => ConstGauge::new(i64::try_from(n).unwrap_or(i64::MAX)).encode(encoder),
        (_, Value::Real(x)) => ConstGauge::new(x).encode(encoder),
    }
}

/// `families` in the OpenMetrics text format, every name after `prefix_`.
pub fn encode(prefix: &str, families: Vec<Family>) -> String {
    let mut registry = Registry::with_prefix(prefix);
    registry.register_collector(Box::new(Constants { families }));
    let mut text = String::new();
    if prometheus_client::encoding::text::encode(&mut text, &registry).is_err() {
        text = format!("# {prefix}: metrics encoding failed\n");
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_counters_and_gauges_with_labels() {
        let mut frames = Family::new(Descriptor::counter("port_frames_out", "Frames written to a port."));
        frames.push(vec![("port", "1".to_owned())], Value::Count(7));
        let mut up = Family::new(Descriptor::gauge("port_up", "Whether the port is open."));
        up.push(vec![("port", "1".to_owned())], Value::Count(1));
        let text = encode("gcud", vec![frames, up]);
        assert!(text.contains("# TYPE gcud_port_frames_out counter"), "{text}");
        assert!(text.contains("gcud_port_frames_out_total{port=\"1\"} 7"), "{text}");
        assert!(text.contains("gcud_port_up{port=\"1\"} 1"), "{text}");
        assert!(text.ends_with("# EOF\n"), "{text}");
    }

    #[test]
    fn a_unit_ends_the_name_and_has_its_line() {
        let seen = Descriptor::gauge("port_last_seen_timestamp", "When.").in_unit(Unit::Seconds);
        let mut family = Family::scoped("x", seen);
        family.push(vec![], Value::Real(1.5));
        let text = encode("gcud", vec![family]);
        assert!(
            text.contains("# TYPE gcud_x_port_last_seen_timestamp_seconds gauge\n"),
            "{text}"
        );
        assert!(
            text.contains("# UNIT gcud_x_port_last_seen_timestamp_seconds seconds\n"),
            "{text}"
        );
        assert!(
            text.contains("\ngcud_x_port_last_seen_timestamp_seconds 1.5\n"),
            "{text}"
        );
    }
}
