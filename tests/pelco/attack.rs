//! What faces the LAN: floods over TCP and UDP (the door's memory and the
//! bus stay bounded, the connection caps hold), and a second keyboard
//! driving against the first (gcud decides; the refused one is logged at
//! INFO and nothing of it reaches the bus).

use super::*;

/// Random-looking bytes (a fixed xorshift: the same every run).
fn noise(n: usize, seed: u64) -> Vec<u8> {
    let mut x = seed | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect()
}

/// The door's commands on the bus that are not queries.
fn door_commands(stack: &Stack) -> Vec<String> {
    stack.door_frames().into_iter().filter(|p| !p.ends_with('?')).collect()
}

#[test]
fn a_tcp_flood_of_noise_and_drives_holds_memory_and_the_bus_and_the_caps_hold() {
    let stack = Stack::start_with(1000, "[limits]\nmax_connections = 4\nmax_connections_per_peer = 4\n");
    let (rss0, _) = memory_kb(stack.door.pid());
    // More connections than the cap: the first four are served, the rest
    // closed at once by the bounded listener.
    let extra: Vec<TcpStream> = (0..12).map(|_| tcp_keyboard(stack.d_tcp)).collect();
    let closed = extra
        .into_iter()
        .filter(|s| {
            let mut s = s;
            s.set_read_timeout(Some(Duration::from_millis(500))).unwrap();
            matches!(s.read(&mut [0u8; 1]), Ok(0) | Err(_))
        })
        .count();
    assert!(closed >= 8, "the connection cap (4) held: {closed} of 12 closed");
    support::eventually("the refusals logged", || {
        stack.door.log().contains("connection refused")
    });
    // 4 MB of noise with a drive right every 1000 bytes, as fast as it goes.
    let mut kb = tcp_keyboard(stack.d_tcp);
    let drive = pelco_d(1, [0x00, 0x02, 0x20, 0x00]);
    let start = stack.position();
    for i in 0..4000u64 {
        let mut chunk = noise(1000, i + 1);
        chunk.extend_from_slice(&drive);
        send_tcp(&mut kb, &chunk);
    }
    support::door::wait_moving(&stack.gcud, MAST, start);
    send_tcp(&mut kb, &pelco_d(1, [0; 4]));
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let (rss, peak) = memory_kb(stack.door.pid());
    eprintln!("gimbal-pelco memory: {rss0} kB before, {rss} kB after 4 MB of TCP flood (peak {peak} kB)");
    assert!(peak < rss0 + 16 * 1024, "memory grew: {rss0} kB -> peak {peak} kB");
    // Four thousand drives in one direction at one speed are one drive on the bus.
    let sent = door_commands(&stack);
    assert!(sent.len() <= 8, "the bus saw the flood: {sent:?}");
    assert!(stack.door.log().contains("skipped"));
}

#[test]
fn a_udp_flood_from_many_sources_holds_memory_and_the_bus_and_the_door_still_answers() {
    let stack = Stack::start_with(1000, "[limits]\nudp_sources = 16\n");
    let (rss0, _) = memory_kb(stack.door.pid());
    let door = ("127.0.0.1", stack.d_udp);
    let drive = pelco_d(1, [0x00, 0x10, 0x00, 0x20]);
    let start = stack.position();
    let sockets: Vec<UdpSocket> = (0..64).map(|_| udp_keyboard()).collect();
    for i in 0..40_000u64 {
        let s = &sockets[(i % 64) as usize];
        let mut d = noise(200, i + 7);
        if i % 10 == 0 {
            d.extend_from_slice(&drive);
        }
        let _ = s.send_to(&d, door);
    }
    support::door::wait_moving(&stack.gcud, MAST, start);
    let kb = udp_keyboard();
    kb.send_to(&pelco_d(1, [0; 4]), door).expect("send");
    // The stop of a keyboard that started nothing stops nothing: the
    // lease stops the flood's drive.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    kb.send_to(&pelco_d(1, [0x00, 0x53, 0x00, 0x00]), door).expect("send");
    let mut answer = [0u8; 16];
    let (n, _) = kb.recv_from(&mut answer).expect("the door still answers");
    assert_eq!(&answer[..4], &[0xFF, 0x01, 0x00, 0x5B], "{:02X?}", &answer[..n]);
    let (rss, peak) = memory_kb(stack.door.pid());
    eprintln!("gimbal-pelco memory: {rss0} kB before, {rss} kB after 40000 datagrams from 64 sources (peak {peak} kB)");
    assert!(peak < rss0 + 16 * 1024, "memory grew: {rss0} kB -> peak {peak} kB");
    let sent = door_commands(&stack);
    assert!(sent.len() <= 12, "the bus saw the flood: {sent:?}");
}

/// gcud with the mast gimbal and a TLS listener `doors` whose clients are
/// principals: the door (`gimbal-pelco`, acting for users), the control
/// room's desk keyboard (priority 80) and a DVR (50).
fn tls_gcud(pki: &std::path::Path) -> Gcud {
    let p = pki.display();
    Gcud::start(&format!(
        "[gcu]\ngroup = {group}\n[control]\nhold_ms = 60000\n\
         [[port]]\nid = 1\nsimulate = [1]\n\
         {clients}allow_source_groups = [0, {DOOR_GROUP}]\n\
         [[link]]\nname = \"doors\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = 100\n\
         allow_source_groups = [0, {DOOR_GROUP}]\n\
         tls = {{ cert = \"{p}/gcud.crt\", key = \"{p}/gcud.key\", client_ca = \"{p}/ca.crt\" }}\n\
         [[principal]]\nname = \"gimbal-pelco\"\npriority = 90\nacts_for_users = true\n\
         [[principal]]\nname = \"desk\"\npriority = 80\n\
         [[principal]]\nname = \"dvr\"\npriority = 50\n",
        group = support::door::GCUD_GROUP,
        clients = support::gcud::CLIENTS,
    ))
}

#[test]
fn a_second_keyboard_driving_against_the_first_is_refused_by_gcud_and_logged_at_info() {
    let dir = tempfile::tempdir().expect("temp dir");
    let pki = dir.path().join("tls");
    support::tls_init(&pki, &["gimbal-pelco"]);
    let gcud = tls_gcud(&pki);
    let doors = gcud.address("listening link=doors");
    let p = pki.display();
    let mut door = Door::new("gimbal-pelco", env!("CARGO_BIN_EXE_gimbal-pelco"));
    door.start(&format!(
        "gcud = \"tls://{doors}\"\n\
         gcud_tls = {{ ca = \"{p}/ca.crt\", cert = \"{p}/gimbal-pelco.crt\", key = \"{p}/gimbal-pelco.key\" }}\n\
         source_group = {DOOR_GROUP}\n\
         [[input]]\ntcp_listen = \"127.0.0.1:0\"\nprotocol = \"pelco-d\"\nprincipal = \"desk\"\n\
         [[input]]\ntcp_listen = \"127.0.0.1:0\"\nprotocol = \"pelco-d\"\nprincipal = \"dvr\"\n\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"{MAST}\"\npelco_address = 1\n"
    ));
    let mut desk = tcp_keyboard(door.port("input[0] tcp_listen"));
    let mut dvr = tcp_keyboard(door.port("input[1] tcp_listen"));
    let right = pelco_d(1, [0x00, 0x02, 0x10, 0x00]);
    let left = pelco_d(1, [0x00, 0x04, 0x3F, 0x00]);
    let start = gcud.position(MAST);
    hold(&mut |f| send_tcp(&mut desk, f), &right, 0.5);
    support::door::wait_moving(&gcud, MAST, start);
    // The DVR drives left while the desk holds its stick right.
    for _ in 0..10 {
        send_tcp(&mut desk, &right);
        send_tcp(&mut dvr, &left);
        std::thread::sleep(Duration::from_millis(100));
    }
    let line = support::wait_for_log_line(&door.log_path(), "gcud refused the drive");
    assert!(line.contains(" INFO "), "the refusal is logged at INFO: {line}");
    assert!(
        line.contains("for input[1]") && line.contains("principal dvr"),
        "the DVR's: {line}"
    );
    assert!(
        !door
            .log()
            .lines()
            .any(|l| l.contains("gcud refused") && l.contains("for input[0]")),
        "the desk was not refused:\n{}",
        door.log()
    );
    gcud.wait_for_log("dvr");
    // The DVR's stop stops nothing of the desk's; the desk's own does.
    let moving = gcud.position(MAST);
    send_tcp(&mut dvr, &pelco_d(1, [0; 4]));
    send_tcp(&mut desk, &right);
    support::door::wait_moving(&gcud, MAST, moving);
    let received = gcud.received(MAST);
    assert!(
        !received.iter().any(|(from, p)| *from == DOOR_GROUP && p == "PL"),
        "the DVR's drive reached the bus: {received:?}"
    );
    send_tcp(&mut desk, &pelco_d(1, [0; 4]));
    support::door::wait_for_stop(&gcud, MAST, DOOR_GROUP, "PS");
}
