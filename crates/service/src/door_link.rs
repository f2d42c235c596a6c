//! The keys at the top of every front door's file, read in one place:
//! its way to gcud (`gcud`, `gcud_tls`), the source group of its commands
//! (`source_group`), how often its sessions poll (`poll_ms`, where the
//! door polls), gcud's NIC window (`nic_window_ms`, 1.4.2) and its own
//! metrics (`[metrics] listen`, [`crate::door_metrics`]: checked here,
//! served by the start-up, [`metrics_listen`]).
//!
//! A door's file is read as [`DoorFile`]: these keys into [`LinkKeys`],
//! every other key into the door's own struct, which keeps
//! `deny_unknown_fields` (serde's `flatten` cannot: it buffers the table,
//! which loses both the unknown-key check and the values' spans). Each
//! key is read once, in the file's order, at its place: an error still
//! names the file, line, column and key, and an unknown key's message
//! lists every key the door takes, these first.

use std::fmt;
use std::marker::PhantomData;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use serde::de::value::{MapAccessDeserializer, StrDeserializer};
use serde::de::{self, DeserializeOwned, DeserializeSeed, MapAccess, Visitor};
use serde::{Deserialize, Deserializer};
use toml::Spanned;

use crate::config_file::{ConfigError, Int, Millis, Source};
use crate::door_metrics::MetricsSection;

/// `poll_ms`'s default for a door that takes no `poll_ms` (the key is
/// then unknown there).
pub const NO_POLL: i64 = 0;

/// A door's `gcud_tls = { ca, cert, key }`, as written
/// ([`gcud_endpoint`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GcudTlsSection {
    ca: String,
    cert: Option<String>,
    key: Option<String>,
}

/// A door's way to gcud: `gcud = "HOST:PORT"`, or `"tls://HOST:PORT"`
/// with `gcud_tls = { ca, cert, key }` (the CA of gcud's certificate,
/// the door's own certificate and key: its principal at gcud). The
/// files are read now, so that an error names them.
pub fn gcud_endpoint(
    c: &Source<'_>,
    v: &Spanned<String>,
    tls: Option<&Spanned<GcudTlsSection>>,
) -> Result<sagebrush_host::tls::Endpoint, ConfigError> {
    let text = v.get_ref();
    let plain = text.strip_prefix(sagebrush_host::tls::TLS_SCHEME).unwrap_or(text);
    let checked = Spanned::new(v.span(), plain.to_owned());
    c.gcud_address(&checked)?;
    let files = match tls {
        None => None,
        Some(t) => {
            let raw = t.get_ref();
            let identity = match (&raw.cert, &raw.key) {
                (Some(c), Some(k)) => Some((PathBuf::from(c), PathBuf::from(k))),
                (None, None) => None,
                _ => return Err(c.at(t.span(), "gcud_tls", "expected `cert` and `key` together")),
            };
            let files = sagebrush_host::tls::ClientFiles {
                ca: PathBuf::from(&raw.ca),
                identity,
            };
            let identity = files.identity.as_ref().map(|(c, k)| (c.as_path(), k.as_path()));
            sagebrush_host::tls::connector(&files.ca, identity)
                .map_err(|e| c.at(t.span(), "gcud_tls", e.to_string()))?;
            Some(files)
        }
    };
    sagebrush_host::tls::Endpoint::parse(text, files).map_err(|e| c.at(v.span(), "gcud", e))
}

/// The keys every door shares, as written; `POLL_MS` is the door's
/// `poll_ms` default ([`NO_POLL`]: the door takes no `poll_ms`).
#[derive(Debug, Default)]
pub struct LinkKeys<const POLL_MS: i64> {
    gcud: Option<Spanned<String>>,
    gcud_tls: Option<Spanned<GcudTlsSection>>,
    source_group: Int<u8, 0, 254>,
    poll_ms: Option<Millis<20, 10_000>>,
    nic_window_ms: Millis<10, 1000, 100>,
    metrics: Option<MetricsSection>,
}

/// One of the shared keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LinkKey {
    Gcud,
    GcudTls,
    SourceGroup,
    PollMs,
    NicWindowMs,
    Metrics,
}

/// The shared keys by name, in the order an unknown key's message lists them.
const LINK_KEYS: [(&str, LinkKey); 6] = [
    ("gcud", LinkKey::Gcud),
    ("gcud_tls", LinkKey::GcudTls),
    ("source_group", LinkKey::SourceGroup),
    ("poll_ms", LinkKey::PollMs),
    ("nic_window_ms", LinkKey::NicWindowMs),
    ("metrics", LinkKey::Metrics),
];

/// The shared keys, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct DoorLink {
    /// `gcud` (and `gcud_tls`): gcud's client listener.
    pub gcud: sagebrush_host::tls::Endpoint,
    /// `source_group`: the source group of the door's commands.
    pub source_group: u8,
    /// `nic_window_ms`: how long after gcud's ACK a NIC may come (1.4.2).
    pub nic_window: Duration,
    /// `poll_ms`, or the door's default (zero for a door without it).
    pub poll: Duration,
}

impl<const POLL_MS: i64> LinkKeys<POLL_MS> {
    /// The keys this door takes.
    fn taken() -> impl Iterator<Item = (&'static str, LinkKey)> {
        LINK_KEYS
            .into_iter()
            .filter(|(_, k)| POLL_MS != NO_POLL || *k != LinkKey::PollMs)
    }

    /// Reads the value of `key` from `map`, at its place.
    fn read<'de, A: MapAccess<'de>>(&mut self, key: LinkKey, map: &mut A) -> Result<(), A::Error> {
        match key {
            LinkKey::Gcud => self.gcud = Some(map.next_value()?),
            LinkKey::GcudTls => self.gcud_tls = Some(map.next_value()?),
            LinkKey::SourceGroup => self.source_group = map.next_value()?,
            LinkKey::PollMs => self.poll_ms = Some(map.next_value()?),
            LinkKey::NicWindowMs => self.nic_window_ms = map.next_value()?,
            LinkKey::Metrics => self.metrics = Some(map.next_value()?),
        }
        Ok(())
    }

    /// Validates the keys (gcud first: its TLS files are read now).
    pub fn resolve(&self, c: &Source<'_>) -> Result<DoorLink, ConfigError> {
        const {
            assert!(
                POLL_MS == NO_POLL || (20 <= POLL_MS && POLL_MS <= 10_000),
                "poll_ms's default"
            )
        };
        let Some(gcud) = &self.gcud else {
            return Err(c.at(0..0, "", "missing field `gcud`"));
        };
        let gcud = gcud_endpoint(c, gcud, self.gcud_tls.as_ref())?;
        let default_poll = Duration::from_millis(POLL_MS.unsigned_abs());
        let link = DoorLink {
            gcud,
            source_group: self.source_group.get(),
            nic_window: self.nic_window_ms.duration(),
            poll: self.poll_ms.as_ref().map_or(default_poll, Millis::duration),
        };
        // Checked here, at its place; served by the start-up ([`metrics_listen`]).
        c.metrics_listen(self.metrics.as_ref())?;
        Ok(link)
    }
}

/// `[metrics] listen` of a door's file (none when absent), read alone:
/// the door's start-up serves the metrics (`crate::door::main`) after
/// the door's own parse checked the key with the others.
pub fn metrics_listen(file: &std::path::Path, text: &str) -> Result<Option<SocketAddr>, ConfigError> {
    #[derive(Deserialize)]
    struct Metrics {
        metrics: Option<MetricsSection>,
    }
    let c = Source::new(file, text);
    let read: Metrics = c.deserialize()?;
    c.metrics_listen(read.metrics.as_ref())
}

impl Source<'_> {
    /// The file read as a door's ([`DoorFile`]): the shared keys,
    /// validated, and the door's own `T`, as written.
    pub fn door_file<T: DeserializeOwned, const POLL_MS: i64>(&self) -> Result<(DoorLink, T), ConfigError> {
        let file: DoorFile<T, POLL_MS> = self.deserialize()?;
        Ok((file.link.resolve(self)?, file.door))
    }
}

/// A door's whole file: the shared keys, and `T`, the door's own (a
/// struct with `deny_unknown_fields` that leaves the shared keys out).
#[derive(Debug)]
pub struct DoorFile<T, const POLL_MS: i64> {
    pub link: LinkKeys<POLL_MS>,
    pub door: T,
}

impl<'de, T: Deserialize<'de>, const POLL_MS: i64> Deserialize<'de> for DoorFile<T, POLL_MS> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(FileVisitor(PhantomData))
    }
}

struct FileVisitor<T, const POLL_MS: i64>(PhantomData<T>);

impl<'de, T: Deserialize<'de>, const POLL_MS: i64> Visitor<'de> for FileVisitor<T, POLL_MS> {
    type Value = DoorFile<T, POLL_MS>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a table")
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Value, A::Error> {
        let mut link = LinkKeys::default();
        let door = T::deserialize(MapAccessDeserializer::new(Split { map, link: &mut link }))?;
        Ok(DoorFile { link, door })
    }
}

/// The file's table as the door's struct sees it: the shared keys are
/// read into `link` on the way.
struct Split<'a, A, const POLL_MS: i64> {
    map: A,
    link: &'a mut LinkKeys<POLL_MS>,
}

impl<'de, A: MapAccess<'de>, const POLL_MS: i64> MapAccess<'de> for Split<'_, A, POLL_MS> {
    type Error = A::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(&mut self, seed: K) -> Result<Option<K::Value>, A::Error> {
        let mut seed = seed;
        loop {
            match self.map.next_key_seed(KeyOf::<K, POLL_MS>(seed))? {
                None if self.link.gcud.is_none() => return Err(de::Error::missing_field("gcud")),
                None => return Ok(None),
                Some(Key::Door(key)) => return Ok(Some(key)),
                Some(Key::Link(key, unused)) => {
                    self.link.read(key, &mut self.map)?;
                    seed = unused;
                }
            }
        }
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, A::Error> {
        self.map.next_value_seed(seed)
    }
}

/// A key of the file: a shared one (with the door's seed, unused), or the
/// door's own as its struct reads it.
enum Key<K, V> {
    Link(LinkKey, K),
    Door(V),
}

/// Reads a key inside the TOML deserializer's own call, so that an error
/// (an unknown key) gets the key's place.
struct KeyOf<K, const POLL_MS: i64>(K);

impl<'de, K: DeserializeSeed<'de>, const POLL_MS: i64> DeserializeSeed<'de> for KeyOf<K, POLL_MS> {
    type Value = Key<K, K::Value>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_str(self)
    }
}

impl<'de, K: DeserializeSeed<'de>, const POLL_MS: i64> Visitor<'de> for KeyOf<K, POLL_MS> {
    type Value = Key<K, K::Value>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a key")
    }

    fn visit_str<E: de::Error>(self, key: &str) -> Result<Self::Value, E> {
        if let Some((_, k)) = LinkKeys::<POLL_MS>::taken().find(|(name, _)| *name == key) {
            return Ok(Key::Link(k, self.0));
        }
        self.0
            .deserialize(StrDeserializer::<KeyError>::new(key))
            .map(Key::Door)
            .map_err(|e| match e {
                KeyError::Unknown(field, door) => {
                    let all: Vec<String> = LinkKeys::<POLL_MS>::taken()
                        .map(|(name, _)| name)
                        .chain(door.iter().copied())
                        .map(|name| format!("`{name}`"))
                        .collect();
                    E::custom(format_args!(
                        "unknown field `{field}`, expected one of {}",
                        all.join(", ")
                    ))
                }
                KeyError::Other(message) => E::custom(message),
            })
    }
}

/// The door's struct's answer to a key: unknown (with the keys it
/// takes), or another error.
#[derive(Debug)]
enum KeyError {
    Unknown(String, &'static [&'static str]),
    Other(String),
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KeyError::Unknown(field, _) => write!(f, "unknown field `{field}`"),
            KeyError::Other(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for KeyError {}

impl de::Error for KeyError {
    fn custom<M: fmt::Display>(message: M) -> Self {
        KeyError::Other(message.to_string())
    }

    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        KeyError::Unknown(field.to_owned(), expected)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Own {
        name: Spanned<String>,
        #[serde(default)]
        lease_ms: Millis<100, 1000, 500>,
    }

    fn parse<const POLL_MS: i64>(text: &str) -> Result<(DoorLink, Own), String> {
        Source::new(Path::new("d.toml"), text)
            .door_file::<Own, POLL_MS>()
            .map_err(|e| e.to_string())
    }

    #[test]
    fn the_shared_keys_and_the_doors_own_in_any_order() {
        let (link, own) = parse::<200>(
            "name = \"a\"\ngcud = \"127.0.0.1:4001\"\nlease_ms = 300\nsource_group = 7\n\
             [metrics]\nlisten = \"127.0.0.1:9100\"\n",
        )
        .unwrap();
        assert_eq!(own.name.get_ref(), "a");
        assert_eq!(own.lease_ms.get(), 300);
        assert_eq!(link.source_group, 7);
        assert_eq!(link.poll, Duration::from_millis(200));
        assert_eq!(link.nic_window, Duration::from_millis(100));
        let text = "gcud = \"127.0.0.1:4001\"\n[metrics]\nlisten = \"127.0.0.1:9100\"\n";
        assert_eq!(
            metrics_listen(Path::new("d.toml"), text).unwrap(),
            Some("127.0.0.1:9100".parse().unwrap())
        );
        let (link, _) = parse::<200>("gcud = \"127.0.0.1:4001\"\npoll_ms = 50\nname = \"a\"\n").unwrap();
        assert_eq!(link.poll, Duration::from_millis(50));
    }

    #[test]
    fn errors_keep_their_place_key_and_words() {
        let good = "gcud = \"127.0.0.1:4001\"\nname = \"a\"\n";
        assert_eq!(
            parse::<200>(&format!("{good}poll_ms = 5\n")).unwrap_err(),
            "d.toml:3:11: poll_ms: expected an integer 20..=10000, found 5"
        );
        assert_eq!(
            parse::<200>(&format!("{good}lease_ms = 5\n")).unwrap_err(),
            "d.toml:3:12: lease_ms: expected an integer 100..=1000, found 5"
        );
        assert_eq!(
            parse::<200>(&format!("{good}lease = 5\n")).unwrap_err(),
            "d.toml:3:1: lease: unknown field `lease`, expected one of `gcud`, `gcud_tls`, `source_group`, \
             `poll_ms`, `nic_window_ms`, `metrics`, `name`, `lease_ms`"
        );
        assert!(
            parse::<NO_POLL>(&format!("{good}poll_ms = 50\n"))
                .unwrap_err()
                .starts_with("d.toml:3:1: poll_ms: unknown field `poll_ms`, expected one of `gcud`, `gcud_tls`, `source_group`, `nic_window_ms`")
        );
        assert_eq!(
            parse::<200>(&format!("{good}[metrics]\nlisten = \"x\"\n")).unwrap_err(),
            "d.toml:4:10: metrics.listen: expected IP:PORT: \"x\" has no port"
        );
        assert_eq!(
            parse::<200>(&format!("{good}[metrics]\nport = 1\n")).unwrap_err(),
            "d.toml:4:1: metrics.port: unknown field `port`, expected `listen`"
        );
        assert_eq!(
            parse::<200>("name = \"a\"\n").unwrap_err(),
            "d.toml: missing field `gcud`"
        );
        assert_eq!(
            parse::<200>("gcud = \"127.0.0.1:4001\"\n").unwrap_err(),
            "d.toml: missing field `name`"
        );
        assert_eq!(
            parse::<200>("gcud = \"4001\"\nname = \"a\"\n").unwrap_err(),
            "d.toml:1:8: gcud: expected HOST:PORT of gcud's client listener: \"4001\" has no port"
        );
    }
}
