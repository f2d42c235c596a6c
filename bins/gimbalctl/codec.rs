//! `encode` and `decode`: frames to hex and hex to framer events, without
//! I/O (Table 1; the framer's resynchronisation rules of protocol-notes "Framing").

use std::io::Read;

use sagebrush_host::hex::{from_hex, payload_text, to_hex};
use sagebrush_protocol::{Address, Command, FrameBuf, Framer, OwnedEvent};
use serde_json::{Value, json};

use crate::error::CtlError;

fn address_json(a: &Address) -> Value {
    json!({ "group": a.group, "port": a.port, "device": a.device })
}

/// A payload's typed command as JSON, or null for one that fits no command.
fn command_json<E>(command: &Result<Command<'_>, E>) -> Value {
    match command {
        Ok(c) => crate::output::command_json(c),
        Err(_) => Value::Null,
    }
}

/// `gimbalctl encode`: prints the frame for `payload`.
pub fn encode(dest: Address, source: u8, payload: &str, as_json: bool) -> Result<(), CtlError> {
    let bytes = sagebrush_host::hex::payload_bytes(payload)
        .map_err(|e| CtlError::Usage(format!("payload {payload:?}: {e}")))?;
    let frame =
        FrameBuf::new(dest, source, &bytes).map_err(|e| CtlError::Usage(format!("payload {payload:?}: {e}")))?;
    let command = Command::parse_strict(&bytes);
    if let Err(e) = &command {
        sagebrush_host::errln!(
            "gimbalctl: note: {payload:?} is no rev 1.9 command ({e}); a device answers it with NIC"
        );
    }
    let hex = to_hex(frame.as_bytes());
    if as_json {
        let f = frame.frame();
        let value = json!({
            "hex": hex,
            "dest": address_json(&f.dest),
            "source": f.source,
            "payload": payload_text(f.payload()),
            "checksum": f.checksum(),
            "command": command_json(&command),
        });
        sagebrush_host::outln!("{value}");
    } else {
        sagebrush_host::outln!("{hex}");
    }
    Ok(())
}

/// One framer event, or a run of bytes the framer skipped as noise.
#[expect(
    clippy::large_enum_variant,
    reason = "a decode prints a few events once; boxing would only hide the frame behind a pointer"
)]
enum Decoded {
    Event(OwnedEvent),
    Noise(u64),
}

fn print(event: &Decoded, as_json: bool) {
    let (text, value) = match event {
        Decoded::Event(OwnedEvent::Frame(frame)) => {
            let f = frame.frame();
            let command = Command::parse_strict(f.payload());
            let typed = match &command {
                Ok(c) => match crate::output::command_json(c) {
                    Value::Object(m) => m
                        .iter()
                        .filter(|(k, _)| k.as_str() != "mnemonic")
                        .map(|(k, v)| format!("{k}={v}"))
                        .fold(c.mnemonic().to_string(), |acc, kv| acc + " " + &kv),
                    _ => c.mnemonic().to_string(),
                },
                Err(e) => format!("none ({e})"),
            };
            (
                format!(
                    "frame dest {} source {} payload \"{}\" checksum {:02X} command {typed}",
                    f.dest,
                    f.source,
                    payload_text(f.payload()),
                    f.checksum()
                ),
                json!({
                    "kind": "frame",
                    "dest": address_json(&f.dest),
                    "source": f.source,
                    "payload": payload_text(f.payload()),
                    "length": f.payload().len(),
                    "checksum": f.checksum(),
                    "command": command_json(&command),
                }),
            )
        }
        Decoded::Event(OwnedEvent::Ack) => ("ack".into(), json!({ "kind": "ack" })),
        Decoded::Event(OwnedEvent::Nak) => ("nak".into(), json!({ "kind": "nak" })),
        Decoded::Event(OwnedEvent::Nic) => ("nic".into(), json!({ "kind": "nic" })),
        Decoded::Event(OwnedEvent::BadChecksum(b)) => (
            format!(
                "bad_checksum dest {} source {} length {} expected {:02X} found {:02X} at offset {}",
                b.dest, b.source, b.payload_len, b.expected, b.found, b.offset
            ),
            json!({
                "kind": "bad_checksum",
                "dest": address_json(&b.dest),
                "source": b.source,
                "length": b.payload_len,
                "expected": b.expected,
                "found": b.found,
                "offset": b.offset,
            }),
        ),
        Decoded::Noise(n) => (format!("noise {n} byte(s)"), json!({ "kind": "noise", "bytes": n })),
    };
    if as_json {
        sagebrush_host::outln!("{value}");
    } else {
        sagebrush_host::outln!("{text}");
    }
}

/// Every event of `bytes`, with the noise runs between them. The framer
/// counts skipped bytes instead of reporting them: growth of that count
/// before an event (or at the end) is a noise run. A rejected candidate's
/// own `0xF8` is counted as skipped with its `bad_checksum` event, so it is
/// not reported as noise; the rest of a damaged frame's span is.
fn events(bytes: &[u8]) -> Vec<Decoded> {
    let mut framer: Framer = Framer::new();
    let mut out = Vec::new();
    let mut seen = 0u64;
    let mut input = bytes;
    let mut idle = false;
    loop {
        let pushed = framer.push(input);
        input = &input[pushed..];
        if input.is_empty() && !idle {
            // Nothing more will come: a partial candidate will never complete.
            idle = true;
        }
        if idle {
            framer.line_idle();
        }
        while let Some(event) = framer.next_event() {
            let event = Decoded::Event(event.to_owned());
            let skipped = framer.skipped_bytes();
            let own = u64::from(matches!(event, Decoded::Event(OwnedEvent::BadChecksum(_))));
            let noise = (skipped - seen).saturating_sub(own);
            if noise > 0 {
                out.push(Decoded::Noise(noise));
            }
            seen = skipped;
            out.push(event);
        }
        if input.is_empty() {
            break;
        }
    }
    let tail = framer.skipped_bytes() + framer.buffered() as u64 - seen;
    if tail > 0 {
        out.push(Decoded::Noise(tail));
    }
    out
}

/// `gimbalctl decode`: hex from the arguments, or stdin when there are none.
pub fn decode(args: &[String], as_json: bool) -> Result<(), CtlError> {
    let text = if args.is_empty() {
        let mut s = String::new();
        std::io::stdin()
            .read_to_string(&mut s)
            .map_err(|e| CtlError::Io(format!("cannot read stdin: {e}")))?;
        s
    } else {
        args.join(" ")
    };
    let bytes = from_hex(&text).map_err(|e| CtlError::Usage(format!("hex input: {e}")))?;
    for event in events(&bytes) {
        print(&event, as_json);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(bytes: &[u8]) -> Vec<String> {
        events(bytes)
            .iter()
            .map(|e| match e {
                Decoded::Event(OwnedEvent::Frame(f)) => {
                    format!("frame:{}", String::from_utf8_lossy(f.frame().payload()))
                }
                Decoded::Event(OwnedEvent::Ack) => "ack".into(),
                Decoded::Event(OwnedEvent::Nak) => "nak".into(),
                Decoded::Event(OwnedEvent::Nic) => "nic".into(),
                Decoded::Event(OwnedEvent::BadChecksum(_)) => "bad".into(),
                Decoded::Noise(n) => format!("noise:{n}"),
            })
            .collect()
    }

    #[test]
    fn noise_runs_between_events_and_at_the_end() {
        let frame = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
        let mut bytes = vec![0x41, 0x42];
        bytes.extend_from_slice(&frame);
        bytes.extend_from_slice(&[0x06, 0x15, 0x3F, 0x00]);
        assert_eq!(kinds(&bytes), ["noise:2", "frame:P?", "ack", "nak", "nic", "noise:1"]);
        let mut bad = frame;
        bad[8] = 0xA6;
        assert_eq!(kinds(&bad), ["bad", "noise:8"]);
        assert_eq!(kinds(&frame[..5]), ["noise:5"], "a truncated frame is noise at the end");
    }
}
