//! What a front door does with each signal, as its manual page's SIGNALS
//! section says (`crates/service/src/door.rs`, issue 53): SIGHUP, which an
//! operator sends a daemon to reload, is logged and the door goes on
//! serving (it reads its configuration only at start), where the default
//! action would have ended it; SIGTERM then stops it with exit 0.

mod support;

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use support::door::{DOOR_GROUP, Door};

#[test]
fn a_door_logs_sighup_and_keeps_serving_then_stops_on_sigterm() {
    let gcud = support::door::start_gcud();
    let mut door = Door::new("gimbal-mavlink", env!("CARGO_BIN_EXE_gimbal-mavlink"));
    door.start(&format!(
        "source_group = {DOOR_GROUP}\ngcud = \"{}\"\nsystem_id = 1\n\
         [[endpoint]]\nudp_listen = \"127.0.0.1:0\"\n\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\ncomponent_id = 154\n",
        gcud.clients()
    ));
    let port = door.port("MAVLink UDP endpoint bound");
    let pid = Pid::from_raw(door.pid() as i32);
    kill(pid, Signal::SIGHUP).expect("SIGHUP");
    support::wait_for_log_line(&door.log_path(), "SIGHUP ignored");
    // Still serving: its UDP endpoint is still bound (a second bind fails).
    let taken = std::net::UdpSocket::bind(("127.0.0.1", port));
    assert!(taken.is_err(), "port {port} free after SIGHUP:\n{}", door.log());
    // A door ended by SIGHUP's default action would report the signal here.
    let status = door.signal(Signal::SIGTERM);
    assert!(status.success(), "{status:?}:\n{}", door.log());
}
