//! Raw VISCA over IP datagrams from addresses of our choosing: what the
//! sequence numbers protect (an old drive after a stop), and two client
//! addresses driving one gimbal, decided by gcud.

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use super::*;
use support::HANG_GUARD;
use support::door::{assert_still, wait_for_stop, wait_moving};

/// A VISCA over IP controller on its own address.
pub struct Raw {
    socket: UdpSocket,
    pub sequence: u32,
}

/// `hex` ("81 01 06 04 FF") as bytes.
pub fn hex(text: &str) -> Vec<u8> {
    text.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("hex"))
        .collect()
}

/// A datagram: `kind`, `sequence`, `payload` (Sony's 8-byte header).
pub fn datagram(kind: u16, sequence: u32, payload: &[u8]) -> Vec<u8> {
    let mut d = kind.to_be_bytes().to_vec();
    d.extend((payload.len() as u16).to_be_bytes());
    d.extend(sequence.to_be_bytes());
    d.extend(payload);
    d
}

impl Raw {
    /// Bound to `ip` (a loopback address), talking to the door's camera.
    pub fn new(ip: &str, port: u16) -> Self {
        let socket = UdpSocket::bind((ip, 0)).expect("bind");
        socket.connect((HOST, port)).expect("connect");
        socket.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
        Self { socket, sequence: 0 }
    }

    pub fn send_raw(&self, bytes: &[u8]) {
        self.socket.send(bytes).expect("send");
    }

    /// Sends VISCA `payload` with the next sequence number.
    pub fn send(&mut self, payload: &[u8]) -> u32 {
        self.sequence += 1;
        self.send_raw(&datagram(0x0100, self.sequence, payload));
        self.sequence
    }

    /// The next datagram: (payload type, sequence number, payload).
    pub fn recv(&self) -> (u16, u32, Vec<u8>) {
        let mut buf = [0u8; 64];
        let n = self.socket.recv(&mut buf).expect("a reply before the hang guard");
        assert!(n >= 8, "short reply {:?}", &buf[..n]);
        let kind = u16::from_be_bytes([buf[0], buf[1]]);
        let sequence = u32::from_be_bytes([buf[4], buf[5], buf[6], buf[7]]);
        (kind, sequence, buf[8..n].to_vec())
    }

    /// The VISCA reply to `sequence` within `wait`, if one comes (other
    /// datagrams are skipped).
    pub fn reply_to(&self, sequence: u32, wait: Duration) -> Option<Vec<u8>> {
        self.socket.set_read_timeout(Some(wait)).expect("timeout");
        let mut buf = [0u8; 64];
        let got = loop {
            let Ok(n) = self.socket.recv(&mut buf) else { break None };
            if n > 8 && buf[..2] == [0x01, 0x11] && buf[4..8] == sequence.to_be_bytes() {
                break Some(buf[8..n].to_vec());
            }
        };
        self.socket.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
        got
    }

    /// Sends command `payload` and reads its replies up to the Completion
    /// or error: every reply's payload, each checked to echo the number.
    pub fn command(&mut self, payload: &[u8]) -> Vec<Vec<u8>> {
        let sequence = self.send(payload);
        let mut replies = Vec::new();
        loop {
            let (kind, seq, reply) = self.recv();
            if seq != sequence {
                continue;
            }
            assert_eq!(kind, 0x0111, "a VISCA reply: {reply:?}");
            let done = reply[1] & 0xF0 != 0x40;
            replies.push(reply);
            if done {
                return replies;
            }
        }
    }

    /// RESET: sequence numbers start again. The replies to what was sent
    /// before come first (the door answers in order): skipped, up to the
    /// RESET's ACK.
    /// UDP loses datagrams (a socket buffer full after a flood): the
    /// RESET is sent again every second until its ACK comes.
    pub fn reset(&mut self) {
        self.sequence = 0;
        let started = Instant::now();
        self.socket
            .set_read_timeout(Some(Duration::from_secs(1)))
            .expect("timeout");
        'again: loop {
            assert!(started.elapsed() < HANG_GUARD, "no ACK of RESET");
            self.send_raw(&datagram(0x0200, 0, &[0x01]));
            let mut buf = [0u8; 64];
            loop {
                match self.socket.recv(&mut buf) {
                    Ok(n) if buf[..n] == datagram(0x0201, 0, &[0x01])[..] => break 'again,
                    Ok(_) => {}
                    Err(_) => continue 'again,
                }
            }
        }
        self.socket.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    }
}

const LEFT: &str = "81 01 06 01 08 08 01 03 FF";
const RIGHT: &str = "81 01 06 01 08 08 02 03 FF";
const STOP: &str = "81 01 06 01 08 08 03 03 FF";

/// A drive delayed on the network past the stop after it (its sequence
/// number older) is answered "abnormality in the sequence number" and not
/// carried out: the stop stays the last pan frame on the bus.
#[test]
fn an_old_drive_arriving_after_its_stop_is_refused_and_moves_nothing() {
    let stack = Stack::start();
    let mut c = Raw::new("127.0.0.3", stack.port);
    c.reset();
    let from = stack.position();
    assert_eq!(c.command(&hex(LEFT)), vec![hex("90 41 FF"), hex("90 51 FF")]);
    wait_moving(&stack.gcud, MAST, from);
    assert_eq!(c.command(&hex(STOP)), vec![hex("90 41 FF"), hex("90 51 FF")]);
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let at = stack.gcud.settled_position(MAST);
    let old = c.sequence - 1;
    c.send_raw(&datagram(0x0100, old, &hex(LEFT)));
    let (kind, seq, payload) = c.recv();
    assert_eq!((kind, seq, payload), (0x0201, old, vec![0x0F, 0x01]));
    assert_still(&stack.gcud, MAST, at, "an old drive");
    let sent = stack.door_frames();
    let last = sent.iter().rev().find(|p| ["PL", "PR", "PS"].contains(&p.as_str()));
    assert_eq!(last.map(String::as_str), Some("PS"), "{sent:?}");
    assert!(
        stack.door.log().contains("sequence number older than the last"),
        "{}",
        stack.door.log()
    );
}

/// gcud over TLS knows the door (acting for users) and two users of it,
/// `director` (priority 80) and `guest` (50); the door acts for
/// `director` with 127.0.0.3 and `guest` with 127.0.0.4.
fn governed_stack(dir: &std::path::Path) -> Stack {
    let pki = dir.join("tls");
    support::tls_init(&pki, &["gimbal-visca"]);
    let p = pki.display();
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = {group}\n[control]\nhold_ms = 60000\n\
         [[port]]\nid = 1\nsimulate = [1]\n\
         {clients}allow_source_groups = [0]\n\
         [[link]]\nname = \"doors\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\
         allow_source_groups = [{DOOR_GROUP}]\n\
         tls = {{ cert = \"{p}/gcud.crt\", key = \"{p}/gcud.key\", client_ca = \"{p}/ca.crt\" }}\n\
         [[principal]]\nname = \"gimbal-visca\"\npriority = 90\nacts_for_users = true\n\
         [[principal]]\nname = \"director\"\npriority = 80\n\
         [[principal]]\nname = \"guest\"\npriority = 50\n",
        group = support::door::GCUD_GROUP,
        clients = support::gcud::CLIENTS,
    ));
    let doors = gcud.address("listening link=doors");
    let extra = format!(
        "gcud_tls = {{ ca = \"{p}/ca.crt\", cert = \"{p}/gimbal-visca.crt\", key = \"{p}/gimbal-visca.key\" }}\n\
         [[client]]\naddress = \"127.0.0.3\"\nuser = \"director\"\n[[client]]\naddress = \"127.0.0.4\"\nuser = \"guest\"\n"
    );
    let text = config(&format!("tls://{doors}"), 5000, &extra);
    Stack::start_configured(gcud, &text)
}

/// Two controllers on one camera: gcud decides between them as between
/// any two tools. The director's drive holds the gimbal; the guest's drive
/// against it is answered ACK then `90 61 41 FF`, nothing of it reaches
/// the bus, and the door's log says why in gcud's words.
#[test]
fn a_second_client_address_driving_against_the_first_is_refused_by_gcud() {
    let dir = tempfile::tempdir().expect("temp dir");
    let stack = governed_stack(dir.path());
    let mut director = Raw::new("127.0.0.3", stack.port);
    let mut guest = Raw::new("127.0.0.4", stack.port);
    director.reset();
    guest.reset();
    let from = stack.position();
    assert_eq!(director.command(&hex(LEFT)), vec![hex("90 41 FF"), hex("90 51 FF")]);
    wait_moving(&stack.gcud, MAST, from);
    let before = stack.door_frames().len();
    let started = Instant::now();
    assert_eq!(guest.command(&hex(RIGHT)), vec![hex("90 41 FF"), hex("90 61 41 FF")]);
    eprintln!("the guest's refusal came {:?} after its drive", started.elapsed());
    let after: Vec<String> = stack.door_frames().split_off(before);
    assert!(
        !after.iter().any(|p| p == "PR"),
        "the guest's drive reached the bus: {after:?}"
    );
    let log = stack.door.log();
    assert!(
        log.lines()
            .any(|l| l.contains("drive not executed") && l.contains("director via gimbal-visca")),
        "the door logs gcud's reason, naming the holder: {log}"
    );
    // The director stops its own drive.
    assert_eq!(director.command(&hex(STOP)), vec![hex("90 41 FF"), hex("90 51 FF")]);
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let audit = stack.gcud.log();
    assert!(
        audit.lines().any(|l| l.contains("guest via gimbal-visca: pan right")
            && l.contains("command=PR")
            && l.contains("refused")),
        "gcud's audit names the guest's refused drive:\n{audit}"
    );
}

/// With `lens = true`: CAM_Zoom tele runs `ZI` until the zoom stop's `ZS`,
/// zoom direct goes to its place (`0x2000` of `0x4000`: the middle of the
/// lens's 0..=4095) and the zoom inquiry reads it back; CAM_Focus far at
/// speed 5 sets the focus speed then `FF`, its stop `FS`. Raw VISCA over
/// TCP, each ACKed then completed; read on the bus side.
#[test]
fn a_lens_zooms_and_focuses_over_tcp() {
    use std::io::{Read, Write};
    let gcud = support::door::start_gcud();
    let text =
        config(&gcud.clients(), 5000, "").replace("reuse_address = true\n", "reuse_address = true\nlens = true\n");
    let stack = Stack::start_configured(gcud, &text);
    let zoom = || {
        let out = stack.gcud.ctl(&["--json", "--to", MAST, "lens"]);
        assert_eq!(out.code, 0, "{out:?}");
        out.json()["result"]["zoom"].as_u64().expect("zoom")
    };
    let mut s = std::net::TcpStream::connect(("127.0.0.1", stack.tcp)).expect("connect");
    s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let mut ask = |message: &str, replies: usize| {
        s.write_all(&hex(message)).expect("write");
        let mut got = Vec::new();
        while got.iter().filter(|b| **b == 0xFF).count() < replies {
            let mut buf = [0u8; 64];
            let n = s.read(&mut buf).expect("read");
            assert!(n > 0, "closed");
            got.extend_from_slice(&buf[..n]);
        }
        got
    };
    assert_eq!(ask("81 01 04 07 25 FF", 2), hex("90 41 FF 90 51 FF"));
    support::eventually("ZI on the bus", || stack.door_frames().iter().any(|p| p == "ZI"));
    assert_eq!(ask("81 01 04 07 00 FF", 2), hex("90 41 FF 90 51 FF"));
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "ZS");
    assert_eq!(ask("81 01 04 47 02 00 00 00 FF", 2), hex("90 41 FF 90 51 FF"));
    support::eventually("the zoom at 2048", || zoom() == 2048);
    support::eventually("the zoom inquiry reads 0x2000", || {
        ask("81 09 04 47 FF", 1) == hex("90 50 02 00 00 00 FF")
    });
    assert_eq!(ask("81 01 04 08 25 FF", 2), hex("90 41 FF 90 51 FF"));
    assert_eq!(ask("81 01 04 08 00 FF", 2), hex("90 41 FF 90 51 FF"));
    let sent = stack.door_frames();
    let ff = sent.iter().position(|p| p == "FF").expect("FF on the bus");
    assert!(
        sent[..ff]
            .iter()
            .any(|p| p.starts_with('F') && p.len() == 2 && p != "FF"),
        "a focus speed first: {sent:?}"
    );
    assert!(sent[ff..].iter().any(|p| p == "FS"), "{sent:?}");
}

/// SIGTERM while a drive runs: the door stops the gimbal itself (its own
/// `PS`, not gcud's dead-man) and exits 0.
#[test]
fn sigterm_stops_the_drive_then_the_door_exits() {
    let mut stack = Stack::start();
    let mut c = Raw::new("127.0.0.3", stack.port);
    c.reset();
    let from = stack.position();
    assert_eq!(c.command(&hex(LEFT)), vec![hex("90 41 FF"), hex("90 51 FF")]);
    wait_moving(&stack.gcud, MAST, from);
    let status = stack.door.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}\n{}", stack.door.log());
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    assert!(stack.door.log().contains("counters="), "{}", stack.door.log());
}

/// A RelativePosition sent again with the same sequence number (a
/// retransmission: the reply was lost) is answered again but moves the
/// gimbal once; a new number moves it again.
#[test]
fn a_retransmitted_relative_move_moves_once() {
    let stack = Stack::start();
    let mut c = Raw::new("127.0.0.3", stack.port);
    c.reset();
    let relative = hex("81 01 06 03 18 14 00 00 06 04 00 00 00 00 FF"); // +100 steps of pan: 7.5°
    assert_eq!(c.command(&relative), vec![hex("90 41 FF"), hex("90 51 FF")]);
    support::eventually("7.5°", || stack.gcud.settled_position(MAST) == (7.5, 0.0));
    c.send_raw(&datagram(0x0100, c.sequence, &relative));
    assert_eq!(c.reply_to(c.sequence, HANG_GUARD), Some(hex("90 41 FF")));
    assert_eq!(c.reply_to(c.sequence, HANG_GUARD), Some(hex("90 51 FF")));
    assert_still(&stack.gcud, MAST, (7.5, 0.0), "a retransmitted relative move");
    assert_eq!(c.command(&relative), vec![hex("90 41 FF"), hex("90 51 FF")]);
    support::eventually("15°", || stack.gcud.settled_position(MAST) == (15.0, 0.0));
}
