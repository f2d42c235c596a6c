//! Sagebrush gimbal firmware for the LM3S6965 (QEMU `lm3s6965evb`).
//!
//! UART0 bytes go straight into the `DeviceEndpoint`'s free buffer space
//! (`spare_capacity_mut` + `commit`, the protocol crate's DMA path); the
//! endpoint ACKs, NAKs, answers NIC and sends results (Table 3 header)
//! through the UART. SysTick counts milliseconds: it drives the motion
//! model and the silence time-out (`line_idle`) that abandons a frame cut
//! short. Between events the core sleeps in WFI, woken by SysTick or by the
//! UART receive interrupt.
#![no_std]
#![no_main]

mod board;
mod common;
mod gimbal;
mod serve;

use core::mem::MaybeUninit;

use cortex_m_rt::entry;
use sagebrush_protocol::DeviceEndpoint;

use common::{RX_CAPACITY, init};
use gimbal::Gimbal;

#[entry]
fn main() -> ! {
    // The endpoint (framer buffer, last result) and the gimbal live in
    // static RAM; cortex-m-rt hands `static mut` of the entry function out
    // as `&'static mut`, once. Uninitialised statics go to .bss and are set
    // here, so that their initial values take no flash (.data would).
    static mut ENDPOINT: MaybeUninit<DeviceEndpoint<RX_CAPACITY>> = MaybeUninit::uninit();
    static mut GIMBAL: MaybeUninit<Gimbal> = MaybeUninit::uninit();
    let gimbal = init(GIMBAL, Gimbal::new);
    serve::serve(ENDPOINT, gimbal)
}
