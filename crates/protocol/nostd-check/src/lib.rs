//! Firmware-shaped use of `sagebrush-protocol` with neither `std` nor
//! `alloc`: see Cargo.toml.
#![no_std]

use core::panic::PanicInfo;

use sagebrush_protocol::{
    Address, Command, DeviceEndpoint, DeviceHandler, EndpointConfig, Event, Frame, Framer, MAX_FRAME_LEN, MAX_PAYLOAD,
    Position, Reply, ReplyTo, Response,
};

#[panic_handler]
fn panic(_info: &PanicInfo<'_>) -> ! {
    loop {}
}

/// Builds a frame (Table 1) into `out`; returns its length or 0.
///
/// # Safety
/// `payload` must be valid for `payload_len` bytes and `out` for `out_len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sb_frame_encode(
    group: u8,
    port: u8,
    device: u8,
    source: u8,
    payload: *const u8,
    payload_len: usize,
    out: *mut u8,
    out_len: usize,
) -> usize {
    let payload = unsafe { core::slice::from_raw_parts(payload, payload_len) };
    let out = unsafe { core::slice::from_raw_parts_mut(out, out_len) };
    match Frame::new(Address::new(group, port, device), source, payload) {
        Ok(frame) => frame.encode(out).map_or(0, <[u8]>::len),
        Err(_) => 0,
    }
}

/// Parses one frame; returns its payload length or -1.
///
/// # Safety
/// `bytes` must be valid for `len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sb_frame_parse(bytes: *const u8, len: usize) -> i32 {
    let bytes = unsafe { core::slice::from_raw_parts(bytes, len) };
    match Frame::parse(bytes) {
        Ok((frame, _)) => frame.payload().len() as i32,
        Err(_) => -1,
    }
}

/// Runs bytes through a framer; returns the number of valid frames.
///
/// # Safety
/// `bytes` must be valid for `len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sb_framer_count(bytes: *const u8, len: usize) -> u32 {
    let bytes = unsafe { core::slice::from_raw_parts(bytes, len) };
    let mut framer: Framer = Framer::new();
    let mut frames = 0;
    framer.feed(bytes, |event| frames += matches!(event, Event::Frame(_)) as u32);
    // The DMA path of a smaller framer.
    let mut small: Framer<{ MAX_FRAME_LEN }> = Framer::new();
    let spare = small.spare_capacity_mut();
    let n = spare.len().min(bytes.len());
    spare[..n].copy_from_slice(&bytes[..n]);
    small.commit(n);
    small.line_idle();
    while small.next_event().is_some() {}
    frames
}

/// Parses a command and re-encodes it into `out`; returns the length or 0.
///
/// # Safety
/// `payload` must be valid for `len` bytes, `out` for `out_len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sb_command_roundtrip(payload: *const u8, len: usize, out: *mut u8, out_len: usize) -> usize {
    let payload = unsafe { core::slice::from_raw_parts(payload, len) };
    let out = unsafe { core::slice::from_raw_parts_mut(out, out_len) };
    Command::parse(payload).encode(out).map_or(0, <[u8]>::len)
}

/// Parses a `P?` result and re-encodes it; returns the pan angle or i32::MIN.
///
/// # Safety
/// `payload` must be valid for `len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sb_reply_position(payload: *const u8, len: usize) -> i32 {
    let payload = unsafe { core::slice::from_raw_parts(payload, len) };
    let mut buf = [0u8; MAX_PAYLOAD];
    match Reply::parse(&Command::QueryPosition, payload) {
        Ok(reply @ Reply::Position(p)) if reply.encode(&mut buf).is_ok() => i32::from(p.pan.0),
        _ => i32::MIN,
    }
}

struct Gimbal;

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, _reply_to: ReplyTo, _now: u64) -> Response<'_> {
        match command {
            Command::QueryPosition => Response::Reply(Reply::Position(Position::default())),
            Command::Unknown(_) => Response::Nic,
            _ => Response::Done,
        }
    }
}

/// A device endpoint as firmware runs it: bytes in, answer bytes out.
/// Returns the number of answer bytes written to `out`.
///
/// # Safety
/// `bytes` must be valid for `len` bytes, `out` for `out_len` bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn sb_device_receive(
    device: u8,
    bytes: *const u8,
    len: usize,
    now: u64,
    out: *mut u8,
    out_len: usize,
) -> usize {
    let bytes = unsafe { core::slice::from_raw_parts(bytes, len) };
    let out = unsafe { core::slice::from_raw_parts_mut(out, out_len) };
    let mut endpoint: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(device));
    let mut written = 0;
    let mut sink = |answer: &[u8]| {
        let n = answer.len().min(out.len() - written);
        out[written..written + n].copy_from_slice(&answer[..n]);
        written += n;
    };
    endpoint.receive(bytes, now, &mut Gimbal, &mut sink);
    endpoint.line_idle(now, &mut Gimbal, &mut sink);
    written
}
