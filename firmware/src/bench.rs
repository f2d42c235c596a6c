//! Bench image: the firmware's receive path (endpoint + gimbal handler, fed
//! through `spare_capacity_mut` + `commit` in UART-FIFO-sized chunks) over a
//! canned, typical command stream, timed with SysTick, and the stack
//! high-water mark of the whole run. Results go out over semihosting;
//! build.sh runs it as
//! `qemu-system-arm -M lm3s6965evb -icount shift=0 -semihosting ...`.
//!
//! With `-icount shift=0` QEMU's virtual clock advances one nanosecond per
//! guest instruction, so SysTick counts instructions (QEMU does not emulate
//! DWT CYCCNT). The ratio of instructions to SysTick ticks is measured, not
//! assumed: `cortex_m::asm::delay(n)` runs a two-instruction loop n + 1
//! times.
#![no_std]
#![no_main]

mod gimbal;

// The device crate: its interrupt vector table is linked in.
use tudelft_lm3s6965_pac as _;

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use sagebrush_protocol::{
    ACK, Address, DeviceEndpoint, EndpointConfig, Event, FrameBuf, Framer, MAX_FRAME_LEN, NAK, NIC,
};

use gimbal::Gimbal;

/// The firmware's own sizes.
const RX_CAPACITY: usize = MAX_FRAME_LEN;
const DEVICE: u8 = 1;
/// Bytes per `commit`: what one drain of the 16-byte UART FIFO gives.
const CHUNK: usize = 16;
const PASSES: u32 = 20;
/// Stack painting: every word below the bench's own frame gets this value
/// before the run; the lowest word that lost it is the high-water mark.
const PAINT: u32 = 0xC0FF_EE11;

unsafe extern "C" {
    /// Top of the stack (cortex-m-rt's link.x).
    static _stack_start: u32;
    /// Lowest address the stack may grow to: the end of static RAM.
    static _stack_end: u32;
}

/// Output of the endpoint: counted, and the bare bytes tallied, so that a
/// run that answers wrongly shows in the report.
#[derive(Default)]
struct Sink {
    bytes: u32,
    acks: u32,
    naks: u32,
    nics: u32,
    frames: u32,
}

impl Sink {
    fn take(&mut self, out: &[u8]) {
        self.bytes += out.len() as u32;
        match out {
            [ACK] => self.acks += 1,
            [NAK] => self.naks += 1,
            [NIC] => self.nics += 1,
            _ => self.frames += 1,
        }
    }
}

/// A typical exchange on a bus with this gimbal and a neighbour: polls,
/// moves, presets, status, an unknown command, a frame for another device,
/// a damaged frame, and the master's ACK after every result (1.4.2).
fn build_stream(buf: &mut [u8]) -> usize {
    let me = Address::new(5, 1, DEVICE);
    let other = Address::new(5, 1, 2);
    let commands: [(Address, &[u8], bool); 14] = [
        (me, b"P?", true),
        (me, b"P1000F000", false),
        (me, b"AW", true),
        (me, b"I?", true),
        (me, b"E?", true),
        (other, b"P?", false),
        (me, b"PT", false),
        (me, b"S05", false),
        (me, b"P?05", true),
        (me, b"D?", true),
        (me, b"XY", false),
        (me, b"RP0BB8", false),
        (me, b"P05", false),
        (me, b"P?", true),
    ];
    let mut n = 0;
    let mut put = |bytes: &[u8], n: &mut usize| {
        for &b in bytes {
            if let Some(slot) = buf.get_mut(*n) {
                *slot = b;
                *n += 1;
            }
        }
    };
    for (dest, payload, has_result) in commands {
        if let Ok(frame) = FrameBuf::new(dest, 2, payload) {
            put(frame.as_bytes(), &mut n);
        }
        if has_result {
            put(&[ACK], &mut n);
        }
    }
    // A P? whose checksum was damaged on the line: NAK.
    if let Ok(frame) = FrameBuf::new(me, 2, b"P?") {
        let mut bad = [0u8; 9];
        for (d, s) in bad.iter_mut().zip(frame.as_bytes()) {
            *d = *s;
        }
        bad[8] ^= 0x01;
        put(&bad, &mut n);
    }
    n
}

/// SysTick counts down from 2^24 - 1 at the core clock.
fn start_counter(syst: &mut SYST) {
    syst.disable_interrupt();
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(0x00FF_FFFF);
    syst.clear_current();
    syst.enable_counter();
}

fn elapsed(from: u32, to: u32) -> u32 {
    from.wrapping_sub(to) & 0x00FF_FFFF
}

/// Paints the free stack from its limit up to a margin below our frame.
fn paint_stack() -> (usize, usize) {
    let top = &raw const _stack_start as usize;
    let limit = &raw const _stack_end as usize;
    let here = cortex_m::register::msp::read() as usize - 64;
    let mut at = limit;
    while at < here {
        // SAFETY: [limit, here) is stack memory below the current frame
        // (and its 64-byte margin): nothing lives there yet, it is RAM,
        // and it is word aligned (link.x aligns _stack_end to 4).
        unsafe { core::ptr::write_volatile(at as *mut u32, PAINT) };
        at += 4;
    }
    (top, limit)
}

/// Bytes of stack used at the deepest point since painting.
fn stack_high_water(top: usize, limit: usize) -> usize {
    let mut at = limit;
    // SAFETY: reads words of the painted region, RAM below the current
    // frame, word aligned.
    while at < top && unsafe { core::ptr::read_volatile(at as *const u32) } == PAINT {
        at += 4;
    }
    top - at
}

/// The firmware's receive path over `stream`, `PASSES` times: copy what a
/// FIFO drain gives into the endpoint's spare capacity, commit it. Not
/// inlined, so that the stack it needs is that of the firmware's main loop
/// (a small frame around the endpoint), not of this bench's `main`.
#[inline(never)]
fn run_endpoint(endpoint: &mut DeviceEndpoint<RX_CAPACITY>, gimbal: &mut Gimbal, stream: &[u8], sink: &mut Sink) {
    let mut now = 0u64;
    for _ in 0..PASSES {
        for chunk in stream.chunks(CHUNK) {
            let spare = endpoint.spare_capacity_mut();
            let mut n = 0;
            for (slot, &b) in spare.iter_mut().zip(chunk) {
                *slot = b;
                n += 1;
            }
            endpoint.commit(n, now, gimbal, &mut |out: &[u8]| sink.take(out));
            now += 1;
        }
    }
}

#[entry]
fn main() -> ! {
    static mut ENDPOINT: DeviceEndpoint<RX_CAPACITY> = DeviceEndpoint::new(EndpointConfig::single(DEVICE));
    static mut GIMBAL: Gimbal = Gimbal::new();
    static mut FRAMER: Framer<RX_CAPACITY> = Framer::new();
    // The command stream, built once.
    static mut STREAM: [u8; 512] = [0; 512];
    let (top, limit) = paint_stack();
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        debug::exit(debug::EXIT_FAILURE);
        loop {}
    };
    start_counter(&mut cp.SYST);

    let len = build_stream(STREAM);
    let stream: &[u8] = STREAM.get(..len).unwrap_or_default();

    // Calibration: instructions per SysTick tick.
    const DELAY: u32 = 200_000;
    let t0 = SYST::get_current();
    cortex_m::asm::delay(DELAY);
    let cal_ticks = elapsed(t0, SYST::get_current()).max(1);
    let cal_instructions = 2 * (DELAY + 1);

    // The endpoint, as the firmware drives it.
    let mut sink = Sink::default();
    let sp = cortex_m::register::msp::read() as usize;
    let t0 = SYST::get_current();
    run_endpoint(ENDPOINT, GIMBAL, stream, &mut sink);
    let endpoint_ticks = elapsed(t0, SYST::get_current());
    // Deepest stack of the run below this frame, before printing
    // (formatting goes deeper): what the receive path needs.
    let stack = stack_high_water(top, limit).saturating_sub(top - sp);

    // The framer alone, same chunks, events counted.
    let framer = FRAMER;
    let mut events = 0u32;
    let t0 = SYST::get_current();
    for _ in 0..PASSES {
        for chunk in stream.chunks(CHUNK) {
            framer.push(chunk);
            while let Some(event) = framer.next_event() {
                events += matches!(event, Event::Frame(_)) as u32;
            }
        }
    }
    let framer_ticks = elapsed(t0, SYST::get_current());

    let bytes = len as u64 * u64::from(PASSES);
    let per_byte = |ticks: u32| u64::from(ticks) * u64::from(cal_instructions) / u64::from(cal_ticks) / bytes;
    hprintln!("bench: stream {} bytes x {} passes, chunks of {}", len, PASSES, CHUNK);
    hprintln!(
        "bench: calibration {} instructions = {} SysTick ticks",
        cal_instructions,
        cal_ticks
    );
    hprintln!(
        "bench: endpoint+handler {} instructions/byte; framer alone {} instructions/byte",
        per_byte(endpoint_ticks),
        per_byte(framer_ticks)
    );
    hprintln!(
        "bench: replies acks={} naks={} nics={} frames={} bytes={} framer_frames={}",
        sink.acks,
        sink.naks,
        sink.nics,
        sink.frames,
        sink.bytes,
        events
    );
    hprintln!(
        "bench: receive path stack high-water {} bytes (below the caller's frame)",
        stack
    );
    // Per pass: 13 commands for this gimbal (ACK each), 7 of them with a
    // result, one unknown (NIC), one damaged (NAK); the plain framer sees
    // 14 good frames (one for the neighbour) and the damaged one is no frame.
    let passes = PASSES;
    let ok = sink.acks == 13 * passes
        && sink.frames == 7 * passes
        && sink.nics == passes
        && sink.naks == passes
        && events == 14 * passes;
    if !ok {
        hprintln!("bench: FAILED: unexpected replies");
        debug::exit(debug::EXIT_FAILURE);
    }
    debug::exit(debug::EXIT_SUCCESS);
    loop {}
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}
