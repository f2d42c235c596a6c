//! Wire bytes as hex text: `F8 05 01 0C 02 02 50 3F A5` out; in, any mix of
//! whitespace, commas, `0x` prefixes or none between digit pairs.

/// Upper-case hex bytes separated by single spaces.
pub fn to_hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        s.push_str(&format!("{b:02X}"));
    }
    s
}

/// Parses hex text into bytes; the error names the offending character and
/// its position.
pub fn from_hex(text: &str) -> Result<Vec<u8>, String> {
    let cleaned = text.replace("0x", " ").replace("0X", " ");
    let mut digits = Vec::new();
    for (i, c) in cleaned.char_indices() {
        if c.is_whitespace() || c == ',' || c == ':' {
            continue;
        }
        match c.to_digit(16) {
            Some(d) => digits.push(d as u8),
            None => return Err(format!("{c:?} at position {i} is not a hex digit")),
        }
    }
    if digits.len() % 2 != 0 {
        return Err(format!(
            "odd number of hex digits ({}): bytes are two digits each",
            digits.len()
        ));
    }
    Ok(digits.chunks(2).map(|p| (p[0] << 4) | p[1]).collect())
}

/// Payload bytes as text: printable ASCII as is, anything else as `\xNN`.
pub fn payload_text(payload: &[u8]) -> String {
    let mut s = String::with_capacity(payload.len());
    for &b in payload {
        if (0x20..=0x7E).contains(&b) && b != b'\\' {
            s.push(b as char);
        } else {
            s.push_str(&format!("\\x{b:02X}"));
        }
    }
    s
}

/// The inverse of [`payload_text`]: `\xNN` escapes and `\\` are decoded.
pub fn payload_bytes(text: &str) -> Result<Vec<u8>, String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'\\' {
            match bytes.get(i + 1) {
                Some(b'\\') => {
                    out.push(b'\\');
                    i += 2;
                }
                Some(b'x') => {
                    let pair = text
                        .get(i + 2..i + 4)
                        .ok_or(format!("incomplete \\x escape at position {i}"))?;
                    out.push(
                        u8::from_str_radix(pair, 16).map_err(|_| format!("bad \\x escape {pair:?} at position {i}"))?,
                    );
                    i += 4;
                }
                _ => return Err(format!("unknown escape at position {i}: use \\xNN or \\\\")),
            }
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips() {
        assert_eq!(to_hex(&[0xF8, 0x05, 0x3F]), "F8 05 3F");
        assert_eq!(from_hex("f8 05,0x3F\n06").unwrap(), [0xF8, 0x05, 0x3F, 0x06]);
        assert_eq!(from_hex("F8053F").unwrap(), [0xF8, 0x05, 0x3F]);
        assert!(from_hex("F8 0").unwrap_err().contains("odd"));
        assert!(from_hex("F8 G0").unwrap_err().contains("'G'"));
        assert_eq!(payload_text(b"*x0t\x01\\"), "*x0t\\x01\\x5C");
        assert_eq!(payload_bytes("*x0t\\x01\\\\").unwrap(), b"*x0t\x01\\");
    }
}
