//! The metrics text of every family, byte for byte.

use std::collections::BTreeMap;

use sagebrush_gcu::{LinkKind, LinkStats};

use super::*;
use crate::snapshot::{Heap, fixture};

/// The whole text for a snapshot with every field set: every name,
/// label and value the dashboard and the tests rely on, byte for byte.
#[test]
fn every_family_renders_as_the_reviewed_text() {
    fixture::assert_reviewed("metrics.txt", &render(&fixture::every_field_set()));
}

#[test]
fn every_family_is_declared_once() {
    let text = render(&fixture::every_field_set());
    let mut names = std::collections::BTreeSet::new();
    for line in text.lines().filter_map(|l| l.strip_prefix("# TYPE ")) {
        assert!(names.insert(line.to_owned()), "{line} declared twice");
    }
}
#[test]
fn renders_a_router_snapshot() {
    let mut config = sagebrush_gcu::RouterConfig::new(5);
    config.ports.push(sagebrush_gcu::PortConfig::new(1));
    let mut router = sagebrush_gcu::Router::new(config).unwrap();
    let mut actions = sagebrush_gcu::Outbox::new();
    router.handle(0, sagebrush_gcu::Input::PortOpened { port: 1 }, &mut actions);
    // A P? answered by device 3 at tick 1500: position and Unix times.
    let client = sagebrush_gcu::LinkId(1);
    let link = sagebrush_gcu::LinkConfig::new(LinkKind::Client, sagebrush_gcu::SourceFilter::Any);
    router.handle(
        0,
        sagebrush_gcu::Input::LinkUp {
            link: client,
            config: link,
        },
        &mut actions,
    );
    let frame = |dest: (u8, u8, u8), source: u8, payload: &[u8]| {
        let address = sagebrush_protocol::Address::new(dest.0, dest.1, dest.2);
        sagebrush_protocol::FrameBuf::new(address, source, payload)
            .unwrap()
            .as_bytes()
            .to_vec()
    };
    let command = frame((5, 1, 3), 0, b"P?");
    router.handle(
        0,
        sagebrush_gcu::Input::Bytes {
            line: sagebrush_gcu::LineId::Link(client),
            bytes: &command,
        },
        &mut actions,
    );
    router.handle(
        0,
        sagebrush_gcu::Input::Bytes {
            line: sagebrush_gcu::LineId::Port(1),
            bytes: &[sagebrush_protocol::ACK],
        },
        &mut actions,
    );
    let result = frame((0, 1, 3), 5, b"EECF03E8");
    router.handle(
        1500,
        sagebrush_gcu::Input::Bytes {
            line: sagebrush_gcu::LineId::Port(1),
            bytes: &result,
        },
        &mut actions,
    );
    let mut gone = LinkStats::new(LinkKind::Client);
    gone.line.frames_in = 3;
    let mut live = LinkStats::new(LinkKind::Client);
    live.line.frames_in = 4;
    let mut clients = LinkTotals {
        stats: gone,
        connections: 1,
        listening: true,
    };
    clients.stats.absorb(&live);
    let snapshot = Snapshot {
        stats: router.stats(),
        links: BTreeMap::from([("clients".to_owned(), clients)]),
        connections: Default::default(),
        uptime_ms: 42,
        started_unix_ms: 1_700_000_000_000,
        group: 5,
        name: "test gcu".to_owned(),
        shutting_down: false,
        heap: Heap {
            allocations: 7,
            bytes_in_use: 4096,
        },
        capture: None,
        http: Default::default(),
        control: Vec::new(),
        tours: Vec::new(),
        governance: Default::default(),
        configured: Default::default(),
    };
    let text = render(&snapshot);
    assert!(text.contains("gcud_uptime_ms 42"), "{text}");
    assert!(
        text.contains(&format!(
            "gcud_build_info{{version=\"{VERSION}\",group=\"5\",name=\"test gcu\"}} 1"
        )),
        "{text}"
    );
    assert!(text.contains("gcud_start_time_seconds 1700000000.0"), "{text}");
    assert!(text.contains("gcud_heap_allocations_total 7"), "{text}");
    assert!(text.contains("gcud_heap_bytes 4096"), "{text}");
    let device = "{port=\"1\",device=\"3\"}";
    for line in [
        format!("gcud_device_online{device} 1"),
        format!("gcud_device_position_pan_degrees{device} -44.01"),
        format!("gcud_device_position_tilt_degrees{device} 10.0"),
        format!("gcud_device_position_timestamp_seconds{device} 1700000001.5"),
        format!("gcud_device_last_seen_timestamp_seconds{device} 1700000001.5"),
        "gcud_port_last_seen_timestamp_seconds{port=\"1\"} 1700000001.5".to_owned(),
    ] {
        assert!(text.lines().any(|l| l == line), "{line} missing: {text}");
    }
    assert!(!text.contains("last_seen_ms"), "uptime-based times are gone: {text}");
    assert!(
        text.contains("gcud_link_frames_in_total{link=\"clients\",role=\"client\"} 7"),
        "connections fold into their configured link: {text}"
    );
    assert!(text.contains("gcud_port_open{port=\"1\"} 1"), "{text}");
    assert!(text.contains("gcud_port_retransmits_total{port=\"1\"} 0"), "{text}");
    assert!(
        text.contains("gcud_commands_dropped_total{reason=\"no_route\"} 0"),
        "{text}"
    );
}
