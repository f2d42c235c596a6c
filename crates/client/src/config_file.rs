//! TOML configuration files whose every error names the file, the line and
//! column, the key and what was expected (`--check` prints it and exits 2):
//! reading a file with bounds, parsing it into serde types whose values are
//! [`toml::Spanned`], and locating a value's span for the checks after.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use sagebrush_protocol::Address;
use serde::de::DeserializeOwned;
use toml::Spanned;

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

/// A file's text, to turn spans into places.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    pub file: &'a Path,
    pub text: &'a str,
}

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

    /// An integer within `min..=max`.
    pub fn int<T: TryFrom<i64>>(&self, v: &Spanned<i64>, key: &str, min: i64, max: i64) -> Result<T, ConfigError> {
        let value = *v.get_ref();
        if value < min || value > max {
            return Err(self.at(
                v.span(),
                key,
                format!("expected an integer {min}..={max}, found {value}"),
            ));
        }
        T::try_from(value).map_err(|_| self.at(v.span(), key, format!("expected an integer {min}..={max}")))
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

    /// A travel `[LOW, HIGH]` in degrees within what a position can carry
    /// (±327.67°, Table 15); `default` when not given.
    pub fn travel(
        &self,
        v: Option<&Spanned<Vec<f64>>>,
        key: &str,
        default: (f64, f64),
    ) -> Result<(f64, f64), ConfigError> {
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
        let doc: Doc = src.deserialize().unwrap();
        let e = src.int::<u8>(&doc.count, "count", 1, 254).unwrap_err();
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
