//! TOML configuration files whose every error names the file, the line and
//! column, the key and what was expected (`--check` prints it and exits 2):
//! reading a file with bounds, parsing it into serde types whose values are
//! [`toml::Spanned`], and locating a value's span for the checks after.
//!
//! A setting is typed where it is declared: [`Int`] (an integer within a
//! range, with its default), [`Millis`] (a time in milliseconds, likewise)
//! and [`Baud`] (a rate of the protocol) check their value as the file is
//! parsed, so a value out of range is an error at its own line and column
//! under its own key path, with no hand-written key name. Anything else
//! checked while parsing goes through [`checked`]. [`changed_keys`] names
//! the keys of a section that differ between two validated files (a
//! reload, `--check --against`), from the section's type.

use std::fmt;
use std::marker::PhantomData;
use std::net::SocketAddr;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Duration;

use sagebrush_protocol::{Address, DataRate};
use serde::de::{DeserializeOwned, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use toml::Spanned;

use crate::endpoint;

/// A configuration error with its place in the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConfigError {
    pub file: PathBuf,
    /// 1-based line and column; 0 when the error concerns the whole file.
    pub line: usize,
    pub column: usize,
    /// Dotted key path, e.g. `gimbal[1].listen`; empty for the whole file.
    pub key: String,
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if self.line > 0 {
            write!(f, ":{}:{}", self.line, self.column)?;
        }
        if !self.key.is_empty() {
            write!(f, ": {}", self.key)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ConfigError {}

/// 1-based line and column of byte `offset` in `text`.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// `--check` only: a warning for each serial device (with its place,
/// [`Source::place`]) that does not exist now. Not an error: an adapter may
/// be plugged in later, and `program` opens the line again until it is.
pub fn absent_serial_devices(places: &[(PathBuf, String)], program: &str) -> Vec<String> {
    places
        .iter()
        .filter(|(path, _)| !path.exists())
        .map(|(path, place)| {
            format!(
                "{place}: {} does not exist now; {program} retries it until it is plugged in",
                path.display()
            )
        })
        .collect()
}

/// A file's text, to turn spans into places.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    pub file: &'a Path,
    pub text: &'a str,
}

/// A travel `[LOW, HIGH]`, degrees.
pub type Travel = (f64, f64);

impl<'a> Source<'a> {
    pub fn new(file: &'a Path, text: &'a str) -> Self {
        Self { file, text }
    }

    /// An error at `span` (an empty span at 0: a default, not in the file).
    pub fn at(&self, span: Range<usize>, key: impl Into<String>, message: impl Into<String>) -> ConfigError {
        let (line, column) = if span.start == 0 && span.end == 0 {
            (0, 0)
        } else {
            line_column(self.text, span.start)
        };
        ConfigError {
            file: self.file.to_owned(),
            line,
            column,
            key: key.into(),
            message: message.into(),
        }
    }

    /// The place of `key` at `span`, `FILE:LINE:COLUMN: KEY`, for a warning.
    pub fn place(&self, span: Range<usize>, key: &str) -> String {
        let mut place = self.at(span, key, "").to_string();
        place.truncate(place.len() - 2);
        place
    }

    /// gcud's client listener, `HOST:PORT` (`gcud`).
    pub fn gcud_address(&self, v: &Spanned<String>) -> Result<String, ConfigError> {
        self.host_port(v, "gcud", " of gcud's client listener")
    }

    /// A place to connect to, `HOST:PORT` ([`endpoint::HostPort`]), as
    /// written; `what` ends the expectation (" of a TCP device server").
    pub fn host_port(&self, v: &Spanned<String>, key: &str, what: &str) -> Result<String, ConfigError> {
        match v.get_ref().parse::<endpoint::HostPort>() {
            Ok(_) => Ok(v.get_ref().clone()),
            Err(e) => Err(self.at(v.span(), key, format!("expected HOST:PORT{what}: {e}"))),
        }
    }

    /// An address to listen on, `IP:PORT` ([`endpoint::listen_address`]).
    pub fn listen_address(&self, v: &Spanned<String>, key: &str) -> Result<SocketAddr, ConfigError> {
        endpoint::listen_address(v.get_ref()).map_err(|e| self.at(v.span(), key, format!("expected IP:PORT: {e}")))
    }

    /// The address of one gimbal (`GROUP.PORT.DEVICE`, 1.4.1): no
    /// wildcard 255, no control unit 0.
    pub fn gimbal_address(&self, v: &Spanned<String>, key: &str) -> Result<Address, ConfigError> {
        let address: Address = v.get_ref().parse().map_err(|_| {
            self.at(
                v.span(),
                key,
                "expected GROUP.PORT.DEVICE of one gimbal, e.g. \"5.1.1\"",
            )
        })?;
        if [address.group, address.port, address.device].contains(&255) || address.device == 0 {
            return Err(self.at(
                v.span(),
                key,
                "expected the address of one gimbal (no wildcard 255, no control unit 0)",
            ));
        }
        Ok(address)
    }

    /// A gimbal's name (`key.name`): not empty, and none of the names
    /// `before` it.
    pub fn gimbal_name<'n>(
        &self,
        v: &Spanned<String>,
        key: &str,
        mut before: impl Iterator<Item = &'n str>,
    ) -> Result<String, ConfigError> {
        let name = v.get_ref();
        if name.is_empty() || before.any(|b| b == name) {
            return Err(self.at(
                v.span(),
                format!("{key}.name"),
                "expected a name, not empty and not repeated",
            ));
        }
        Ok(name.clone())
    }

    /// A gimbal's travel (`key.pan_deg`, `key.tilt_deg`): pan, by default
    /// -180..180, and tilt, by default -90..90.
    pub fn pan_tilt_travel(
        &self,
        pan: Option<&Spanned<Vec<f64>>>,
        tilt: Option<&Spanned<Vec<f64>>>,
        key: &str,
    ) -> Result<(Travel, Travel), ConfigError> {
        Ok((
            self.travel(pan, &format!("{key}.pan_deg"), (-180.0, 180.0))?,
            self.travel(tilt, &format!("{key}.tilt_deg"), (-90.0, 90.0))?,
        ))
    }

    /// A travel `[LOW, HIGH]` in degrees within what a position can carry
    /// (±327.67°, Table 15); `default` when not given.
    fn travel(&self, v: Option<&Spanned<Vec<f64>>>, key: &str, default: (f64, f64)) -> Result<(f64, f64), ConfigError> {
        let Some(v) = v else { return Ok(default) };
        match v.get_ref().as_slice() {
            [low, high] if low < high && *low >= -327.67 && *high <= 327.67 => Ok((*low, *high)),
            _ => Err(self.at(
                v.span(),
                key,
                "expected [LOW, HIGH] degrees, LOW < HIGH, within -327.67..=327.67 (Table 15)",
            )),
        }
    }

    /// The text parsed as `T` (the TOML syntax, then the shape: unknown
    /// keys, missing keys and wrong types are errors at their place).
    pub fn deserialize<T: DeserializeOwned>(&self) -> Result<T, ConfigError> {
        let de = toml::de::Deserializer::parse(self.text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            self.at(span, "", e.message().trim().to_owned())
        })?;
        serde_path_to_error::deserialize(de).map_err(|e| {
            // Spanned<T> shows up as an inner private field in the path.
            let key = e.path().to_string().replace(".$__serde_spanned_private_value", "");
            let inner = e.inner();
            let span = inner.span().unwrap_or(0..0);
            self.at(
                span,
                if key == "." { String::new() } else { key },
                in_words(inner.message().trim()),
            )
        })
    }
}

/// serde's type error (`invalid type: string "five", expected i64`) in the
/// words of a TOML file: `expected an integer, found the string "five"`.
fn in_words(message: &str) -> String {
    let Some(rest) = message.strip_prefix("invalid type: ") else {
        return message.to_owned();
    };
    let Some((found, expected)) = rest.rsplit_once(", expected ") else {
        return message.to_owned();
    };
    let expected = match expected {
        "i8" | "i16" | "i32" | "i64" | "u8" | "u16" | "u32" | "u64" | "usize" | "isize" => "an integer",
        "f32" | "f64" => "a number",
        "a boolean" | "bool" => "true or false",
        "a sequence" => "a list [...]",
        "a string" => "a string in quotes",
        "a map" => "a table",
        other => other,
    };
    let found = found
        .replace("sequence", "a list")
        .replace("map", "a table")
        .replace("integer `", "the integer `")
        .replace("string \"", "the string \"")
        .replace("boolean `", "the boolean `")
        .replace("floating point `", "the number `");
    format!("expected {expected}, found {found}")
}

/// Parses a [`Spanned`] `R` and checks it: `check` turns the value into
/// the setting or says, in words, what was expected. A refusal is an error
/// at the value's own place (the TOML deserializer gives an error raised
/// inside a newtype the span of that value, even inside a list) under the
/// value's key path.
pub fn checked<'de, D, R, V>(
    deserializer: D,
    check: impl FnOnce(&R) -> Result<V, String>,
) -> Result<(V, Range<usize>), D::Error>
where
    D: Deserializer<'de>,
    R: Deserialize<'de>,
{
    struct Check<F, R>(F, PhantomData<R>);
    impl<'de, F, R, V> Visitor<'de> for Check<F, R>
    where
        F: FnOnce(&R) -> Result<V, String>,
        R: Deserialize<'de>,
    {
        type Value = (V, Range<usize>);
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a value")
        }
        fn visit_newtype_struct<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
            let value = Spanned::<R>::deserialize(d)?;
            let span = value.span();
            (self.0)(value.get_ref())
                .map(|v| (v, span))
                .map_err(serde::de::Error::custom)
        }
    }
    deserializer.deserialize_newtype_struct("Checked", Check(check, PhantomData))
}

/// The integer types an [`Int`] may hold.
pub trait IntType: Copy + TryFrom<i64> + Serialize + fmt::Debug + PartialEq {}
impl IntType for u8 {}
impl IntType for u16 {}
impl IntType for u32 {}
impl IntType for u64 {}
impl IntType for usize {}
impl IntType for i64 {}

/// An integer setting within `MIN..=MAX`, `DEFAULT` where the key is
/// absent (a field `#[serde(default)]`; an `Option<Int<..>>` has none),
/// with its place in the file. Two are equal when their values are.
#[derive(Clone, Debug)]
pub struct Int<T, const MIN: i64, const MAX: i64, const DEFAULT: i64 = MIN> {
    value: T,
    span: Range<usize>,
}

impl<T: IntType, const MIN: i64, const MAX: i64, const DEFAULT: i64> Int<T, MIN, MAX, DEFAULT> {
    pub fn get(&self) -> T {
        self.value
    }

    /// Where the value is in the file (`0..0`: the default).
    pub fn span(&self) -> Range<usize> {
        self.span.clone()
    }

    /// `value` if it is within the range, else what was expected.
    fn check(value: i64) -> Result<T, String> {
        let expected = || format!("expected an integer {MIN}..={MAX}, found {value}");
        if !(MIN..=MAX).contains(&value) {
            return Err(expected());
        }
        T::try_from(value).map_err(|_| expected())
    }
}

impl<T: IntType, const MIN: i64, const MAX: i64, const DEFAULT: i64> Default for Int<T, MIN, MAX, DEFAULT> {
    fn default() -> Self {
        const { assert!(MIN <= DEFAULT && DEFAULT <= MAX, "the default is outside the range") };
        match Self::check(DEFAULT) {
            Ok(value) => Self { value, span: 0..0 },
            Err(e) => unreachable!("{e}: the type cannot hold the range"),
        }
    }
}

impl<'de, T: IntType, const MIN: i64, const MAX: i64, const DEFAULT: i64> Deserialize<'de>
    for Int<T, MIN, MAX, DEFAULT>
{
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (value, span) = checked(d, |v: &i64| Self::check(*v))?;
        Ok(Self { value, span })
    }
}

impl<T: IntType, const MIN: i64, const MAX: i64, const DEFAULT: i64> Serialize for Int<T, MIN, MAX, DEFAULT> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.value.serialize(s)
    }
}

impl<T: IntType, const MIN: i64, const MAX: i64, const DEFAULT: i64> PartialEq for Int<T, MIN, MAX, DEFAULT> {
    fn eq(&self, other: &Self) -> bool {
        self.value == other.value
    }
}

impl<T: IntType, const MIN: i64, const MAX: i64, const DEFAULT: i64> Eq for Int<T, MIN, MAX, DEFAULT> where T: Eq {}

/// A time in milliseconds within `MIN..=MAX`, `DEFAULT` where the key is
/// absent: an [`Int`] that reads as a [`Duration`] too.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(transparent)]
pub struct Millis<const MIN: i64, const MAX: i64, const DEFAULT: i64 = MIN>(Int<u64, MIN, MAX, DEFAULT>);

impl<const MIN: i64, const MAX: i64, const DEFAULT: i64> Millis<MIN, MAX, DEFAULT> {
    /// The time in milliseconds (the router core's ticks).
    pub fn get(&self) -> u64 {
        self.0.get()
    }

    pub fn duration(&self) -> Duration {
        Duration::from_millis(self.0.get())
    }

    pub fn span(&self) -> Range<usize> {
        self.0.span()
    }
}

/// A line rate of the protocol (1.5.1, Table 4), `DEFAULT` bit/s where the
/// key is absent.
#[derive(Clone, Debug)]
pub struct Baud<const DEFAULT: u32 = 9600> {
    bps: u32,
    span: Range<usize>,
}

impl<const DEFAULT: u32> Baud<DEFAULT> {
    /// Bits per second.
    pub fn get(&self) -> u32 {
        self.bps
    }

    pub fn span(&self) -> Range<usize> {
        self.span.clone()
    }

    fn check(value: i64) -> Result<u32, String> {
        u32::try_from(value)
            .ok()
            .and_then(DataRate::from_bits_per_second)
            .and_then(DataRate::bits_per_second)
            .ok_or_else(|| format!("{}, found {value}", sagebrush_protocol::NotAProtocolRate))
    }
}

impl<const DEFAULT: u32> Default for Baud<DEFAULT> {
    fn default() -> Self {
        match Self::check(i64::from(DEFAULT)) {
            Ok(bps) => Self { bps, span: 0..0 },
            Err(e) => unreachable!("default: {e}"),
        }
    }
}

impl<'de, const DEFAULT: u32> Deserialize<'de> for Baud<DEFAULT> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (bps, span) = checked(d, |v: &i64| Self::check(*v))?;
        Ok(Self { bps, span })
    }
}

impl<const DEFAULT: u32> Serialize for Baud<DEFAULT> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.bps.serialize(s)
    }
}

impl<const DEFAULT: u32> PartialEq for Baud<DEFAULT> {
    fn eq(&self, other: &Self) -> bool {
        self.bps == other.bps
    }
}

impl<const DEFAULT: u32> Eq for Baud<DEFAULT> {}

/// The keys of `section` whose values differ between `old` and `new`, as
/// `SECTION.KEY`: the names are the serialised field names of the
/// section's validated type, which are the file's keys. A section whose
/// values cannot be told apart key by key is named whole.
pub fn changed_keys<T: Serialize + PartialEq>(section: &str, old: &T, new: &T) -> Vec<String> {
    if old == new {
        return Vec::new();
    }
    let table = |v: &T| match toml::Value::try_from(v) {
        Ok(toml::Value::Table(t)) => Some(t),
        _ => None,
    };
    let (Some(old), Some(new)) = (table(old), table(new)) else {
        return vec![section.to_owned()];
    };
    let mut keys: Vec<&String> = old.keys().collect();
    keys.extend(new.keys().filter(|k| !old.contains_key(*k)));
    let changed: Vec<String> = keys
        .into_iter()
        .filter(|k| old.get(*k) != new.get(*k))
        .map(|k| format!("{section}.{k}"))
        .collect();
    if changed.is_empty() {
        vec![section.to_owned()]
    } else {
        changed
    }
}

/// The largest configuration file read (a real one is a few KiB).
pub const MAX_FILE_BYTES: u64 = 1024 * 1024;

/// Reads `file` as text. Only a regular file of at most [`MAX_FILE_BYTES`]
/// is read: the kind and size are checked before any byte is read (a FIFO
/// would block, `/dev/urandom` never ends), the file is opened non-blocking
/// and checked again through its handle, and at most one byte more than the
/// limit is read.
pub fn read(file: &Path) -> Result<String, ConfigError> {
    read_bounded(file).map_err(|message| ConfigError {
        file: file.to_owned(),
        line: 0,
        column: 0,
        key: String::new(),
        message,
    })
}

fn read_bounded(file: &Path) -> Result<String, String> {
    use std::io::Read;
    use std::os::unix::fs::OpenOptionsExt;

    fn kind(m: &std::fs::Metadata) -> Result<(), String> {
        use std::os::unix::fs::FileTypeExt;
        let t = m.file_type();
        let what = if t.is_file() {
            if m.len() > MAX_FILE_BYTES {
                return Err(format!(
                    "cannot read: larger than 1 MiB ({} bytes); expected a configuration file",
                    m.len()
                ));
            }
            return Ok(());
        } else if t.is_dir() {
            "a directory"
        } else if t.is_fifo() {
            "a FIFO"
        } else if t.is_char_device() {
            "a character device"
        } else if t.is_block_device() {
            "a block device"
        } else if t.is_socket() {
            "a socket"
        } else {
            "not a file"
        };
        Err(format!("cannot read: {what}, not a regular file"))
    }

    kind(&std::fs::metadata(file).map_err(|e| format!("cannot read: {e}"))?)?;
    let handle = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(nix::fcntl::OFlag::O_NONBLOCK.bits())
        .open(file)
        .map_err(|e| format!("cannot read: {e}"))?;
    // The path may have been replaced since: check what was opened.
    kind(&handle.metadata().map_err(|e| format!("cannot read: {e}"))?)?;
    let mut bytes = Vec::new();
    handle
        .take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err("cannot read: larger than 1 MiB; expected a configuration file".to_owned());
    }
    String::from_utf8(bytes).map_err(|e| format!("cannot read: not UTF-8 text ({e})"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Doc {
        #[allow(dead_code)]
        name: Spanned<String>,
        #[allow(dead_code)]
        count: Spanned<i64>,
    }

    #[test]
    fn errors_name_the_place_the_key_and_what_was_expected() {
        let file = Path::new("x.toml");
        let text = "name = \"a\"\ncount = \"three\"\n";
        let e = Source::new(file, text).deserialize::<Doc>().unwrap_err();
        assert_eq!((e.line, e.column, e.key.as_str()), (2, 9, "count"), "{e}");
        assert!(e.to_string().starts_with("x.toml:2:9: count: "), "{e}");

        let text = "name = \"a\"\ncount = 3\ncolour = 1\n";
        let e = Source::new(file, text).deserialize::<Doc>().unwrap_err();
        assert_eq!(e.line, 3, "{e}");
        assert!(e.message.contains("colour"), "{e}");

        let text = "name = \"a\"\ncount = 300\n";
        let src = Source::new(file, text);
        #[derive(Debug, Deserialize)]
        struct Ranged {
            #[allow(dead_code)]
            name: Spanned<String>,
            #[allow(dead_code)]
            count: Int<u8, 1, 254>,
        }
        let e = src.deserialize::<Ranged>().unwrap_err();
        let at = |s: &str| Spanned::new(1..2, s.to_owned());
        assert_eq!(src.gimbal_address(&at("5.1.1"), "a"), Ok(Address::new(5, 1, 1)));
        for bad in ["5.1", "5.1.0", "5.255.1", "x"] {
            assert!(src.gimbal_address(&at(bad), "a").is_err(), "{bad}");
        }
        let travel = |v: Vec<f64>| src.travel(Some(&Spanned::new(1..2, v)), "t", (0.0, 1.0));
        assert_eq!(travel(vec![-10.0, 10.0]), Ok((-10.0, 10.0)));
        assert!(travel(vec![10.0, -10.0]).is_err() && travel(vec![0.0, 400.0]).is_err() && travel(vec![1.0]).is_err());
        assert_eq!(src.travel(None, "t", (0.0, 1.0)), Ok((0.0, 1.0)));
        assert_eq!(
            e.to_string(),
            "x.toml:2:9: count: expected an integer 1..=254, found 300"
        );
    }

    #[derive(Debug, Deserialize, Serialize, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Typed {
        group: Int<u8, 1, 254>,
        #[serde(default)]
        depth: Int<usize, 1, 4096, 16>,
        #[serde(default)]
        wait_ms: Millis<10, 10_000, 200>,
        lease_ms: Option<Millis<100, 600_000>>,
        #[serde(default)]
        baud: Baud,
        list: Option<Vec<Int<u8, 0, 254>>>,
    }

    #[test]
    fn typed_settings_check_their_range_at_their_place_and_default_when_absent() {
        let file = Path::new("x.toml");
        let parse = |text: &str| Source::new(file, text).deserialize::<Typed>();
        let t = parse("group = 5\n").unwrap();
        assert_eq!((t.group.get(), t.depth.get(), t.wait_ms.get()), (5, 16, 200));
        assert_eq!((t.baud.get(), t.lease_ms, t.depth.span()), (9600, None, 0..0));
        assert_eq!(t.wait_ms.duration(), Duration::from_millis(200));
        let t = parse("group = 5\nlease_ms = 2000\nbaud = 19200\n").unwrap();
        assert_eq!((t.lease_ms.map(|l| l.get()), t.baud.get()), (Some(2000), 19200));

        let e = parse("group = 5\nwait_ms = 5\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.toml:2:11: wait_ms: expected an integer 10..=10000, found 5"
        );
        let e = parse("group = 255\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.toml:1:9: group: expected an integer 1..=254, found 255"
        );
        let e = parse("group = 5\nlist = [1, 300]\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.toml:2:12: list[1]: expected an integer 0..=254, found 300"
        );
        let e = parse("group = 5\nbaud = 9601\n").unwrap_err();
        assert_eq!((e.line, e.column, e.key.as_str()), (2, 8, "baud"), "{e}");
        assert!(e.message.contains("57600, 115200, found 9601"), "{e}");
        let e = parse("group = \"five\"\n").unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.toml:1:9: group: expected an integer, found the string \"five\""
        );
    }

    #[test]
    fn changed_keys_are_named_from_the_type() {
        let file = Path::new("x.toml");
        let parse = |text: &str| Source::new(file, text).deserialize::<Typed>().unwrap();
        let old = parse("group = 5\n");
        assert_eq!(
            changed_keys("t", &old, &parse("group = 5\ndepth = 16\n")),
            Vec::<String>::new()
        );
        assert_eq!(
            changed_keys("t", &old, &parse("group = 6\nlease_ms = 200\n")),
            ["t.group", "t.lease_ms"]
        );
    }

    #[test]
    fn only_a_bounded_regular_file_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let e = read(dir.path()).unwrap_err();
        assert!(e.message.contains("a directory"), "{e}");
        let big = dir.path().join("big.toml");
        std::fs::write(&big, vec![b'#'; MAX_FILE_BYTES as usize + 1]).unwrap();
        assert!(read(&big).unwrap_err().message.contains("larger than 1 MiB"));
    }
}
