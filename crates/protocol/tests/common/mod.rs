//! Shared proptest strategies and helpers for the integration tests.
#![allow(dead_code)]

use proptest::prelude::*;
use proptest::strategy::Union;
use sagebrush_protocol::*;

/// Leaks `bytes` so that strategies can produce `Command<'static>` and
/// `Reply<'static>`; test processes are short-lived.
pub fn leak(bytes: Vec<u8>) -> &'static [u8] {
    Box::leak(bytes.into_boxed_slice())
}

pub fn axis() -> impl Strategy<Value = Axis> {
    prop_oneof![Just(Axis::Pan), Just(Axis::Tilt)]
}

pub fn u12() -> impl Strategy<Value = U12> {
    (0u16..=4095).prop_map(|v| U12::new(v).unwrap())
}

pub fn limits() -> impl Strategy<Value = Limits> {
    (u12(), u12(), u12(), u12()).prop_map(|(pan_ccw, pan_cw, tilt_ccw, tilt_cw)| Limits {
        pan_ccw,
        pan_cw,
        tilt_ccw,
        tilt_cw,
    })
}

pub fn position() -> impl Strategy<Value = Position> {
    (any::<i16>(), any::<i16>()).prop_map(|(p, t)| Position::new(Angle(p), Angle(t)))
}

pub fn lens() -> impl Strategy<Value = LensPosition> {
    (u12(), u12()).prop_map(|(zoom, focus)| LensPosition { zoom, focus })
}

pub fn data_rate() -> impl Strategy<Value = DataRate> {
    (0u8..=15).prop_map(|c| DataRate::from_code(c).unwrap())
}

pub fn aux_port() -> impl Strategy<Value = AuxPort> {
    (0u8..=1).prop_map(|p| AuxPort::new(p).unwrap())
}

pub fn aux_config() -> impl Strategy<Value = AuxConfig> {
    (
        1u32..=999_999,
        5u8..=8,
        1u8..=2,
        prop_oneof![Just(Parity::None), Just(Parity::Odd), Just(Parity::Even)],
    )
        .prop_map(|(b, d, s, p)| AuxConfig::new(b, d, s, p).unwrap())
}

/// Payloads that parse to no command: random bytes, and near misses that
/// start like real commands.
pub fn unknown_payload() -> impl Strategy<Value = &'static [u8]> {
    let prefixes: Vec<&'static [u8]> = vec![
        b"", b"#", b"A", b"AP", b"C", b"G", b"GR", b"L", b"LS", b"P", b"P?", b"R", b"S", b"S?", b"V", b"VM", b"Z",
        b"*x", b"*x0", b"*x1c,", b"F", b"H", b"T",
    ];
    (
        proptest::sample::select(prefixes),
        proptest::collection::vec(any::<u8>(), 0..12),
    )
        .prop_map(|(p, tail)| [p, &tail[..]].concat())
        .prop_filter("parses to no command", |v| {
            !v.is_empty() && matches!(Command::parse(v), Command::Unknown(_))
        })
        .prop_map(leak)
}

/// Every `Command` variant. [`command_index`] (an exhaustive match) names
/// them, so a new variant breaks the build of the tests until it is added
/// here, and `every_variant_is_generated` checks that all are produced.
pub fn command() -> impl Strategy<Value = Command<'static>> {
    use Command as C;
    let fixed = proptest::sample::select(vec![
        C::AwakeStatus,
        C::QueryMaxDataRate,
        C::Identify,
        C::QueryErrors,
        C::QueryStatusBits,
        C::QueryRateGains,
        C::Initialize,
        C::QueryRelays,
        C::ClearLimits,
        C::QueryLimits,
        C::QueryAccelerations,
        C::Halt,
        C::VerifyHome,
        C::Home,
        C::MotorsStop,
        C::QueryPosition,
        C::PanLeft,
        C::PanRight,
        C::PanStop,
        C::StopMotion,
        C::QueryRates,
        C::TiltDown,
        C::TiltStop,
        C::TiltUp,
        C::CameraOn,
        C::CameraOff,
        C::AutoFocusOn,
        C::FocusFar,
        C::FocusNear,
        C::FocusStop,
        C::AutoFocusOff,
        C::QueryLens,
        C::ZoomIn,
        C::ZoomOut,
        C::ZoomStop,
    ]);
    let strategies: Vec<BoxedStrategy<Command<'static>>> = vec![
        fixed.boxed(),
        (1u8..=254)
            .prop_map(|d| C::SetDeviceId(DeviceId::new(d).unwrap()))
            .boxed(),
        data_rate().prop_map(C::SetDataRate).boxed(),
        (axis(), 3u8..=30)
            .prop_map(|(a, g)| C::SetRateGain(a, RateGain::new(g).unwrap()))
            .boxed(),
        (0u8..=3).prop_map(|r| C::OpenRelay(Relay::new(r).unwrap())).boxed(),
        (0u8..=3).prop_map(|r| C::CloseRelay(Relay::new(r).unwrap())).boxed(),
        limits().prop_map(C::SetLimits).boxed(),
        (axis(), any::<u16>())
            .prop_map(|(a, v)| C::SetAcceleration(a, Acceleration(v)))
            .boxed(),
        axis().prop_map(C::QueryAcceleration).boxed(),
        position().prop_map(C::GoTo).boxed(),
        any::<u8>().prop_map(C::GoToPreset).boxed(),
        any::<u8>().prop_map(C::QueryPreset).boxed(),
        (axis(), any::<u16>()).prop_map(|(a, v)| C::SetRate(a, Rate(v))).boxed(),
        axis().prop_map(C::QueryRate).boxed(),
        any::<u8>().prop_map(C::StorePreset).boxed(),
        (axis(), 0u8..=15)
            .prop_map(|(a, s)| C::SetSpeed(a, Speed::new(s).unwrap()))
            .boxed(),
        any::<u8>().prop_map(C::QueryStoredPreset).boxed(),
        any::<bool>().prop_map(C::SetVectorMode).boxed(),
        (0u8..=9)
            .prop_map(|s| C::FocusSpeed(LensSpeed::new(s).unwrap()))
            .boxed(),
        lens().prop_map(C::LensGoTo).boxed(),
        (0u8..=9).prop_map(|s| C::ZoomSpeed(LensSpeed::new(s).unwrap())).boxed(),
        (10u8..=15)
            .prop_map(|z| C::DigitalZoom(DigitalZoom::new(z).unwrap()))
            .boxed(),
        (aux_port(), aux_config())
            .prop_map(|(p, c)| C::AuxConfigure(p, c))
            .boxed(),
        (aux_port(), proptest::collection::vec(any::<u8>(), 1..=200))
            .prop_map(|(p, d)| C::AuxTransmit(p, AuxBytes::new(leak(d)).unwrap()))
            .boxed(),
        (aux_port(), 1u16..=256)
            .prop_map(|(p, n)| C::AuxReceive(p, AuxReadLen::new(n).unwrap()))
            .boxed(),
        aux_port().prop_map(C::AuxCount).boxed(),
        aux_port().prop_map(C::AuxFlush).boxed(),
        (
            proptest::sample::select(Extended::ALL.to_vec()),
            proptest::collection::vec(any::<u8>(), 0..=252),
        )
            .prop_map(|(e, args)| C::Extended(e, leak(args)))
            .boxed(),
        unknown_payload().prop_map(C::Unknown).boxed(),
    ];
    Union::new(strategies)
}

/// Number of `Command` variants.
pub const COMMAND_VARIANTS: usize = 63;

/// A distinct index per `Command` variant (exhaustive: no wildcard arm).
pub fn command_index(c: &Command<'_>) -> usize {
    use Command as C;
    match c {
        C::SetDeviceId(_) => 0,
        C::AwakeStatus => 1,
        C::QueryMaxDataRate => 2,
        C::SetDataRate(_) => 3,
        C::Identify => 4,
        C::QueryErrors => 5,
        C::QueryStatusBits => 6,
        C::SetRateGain(..) => 7,
        C::QueryRateGains => 8,
        C::Initialize => 9,
        C::OpenRelay(_) => 10,
        C::CloseRelay(_) => 11,
        C::QueryRelays => 12,
        C::ClearLimits => 13,
        C::SetLimits(_) => 14,
        C::QueryLimits => 15,
        C::SetAcceleration(..) => 16,
        C::QueryAccelerations => 17,
        C::QueryAcceleration(_) => 18,
        C::Halt => 19,
        C::VerifyHome => 20,
        C::Home => 21,
        C::MotorsStop => 22,
        C::QueryPosition => 23,
        C::GoTo(_) => 24,
        C::PanLeft => 25,
        C::PanRight => 26,
        C::PanStop => 27,
        C::StopMotion => 28,
        C::GoToPreset(_) => 29,
        C::QueryPreset(_) => 30,
        C::SetRate(..) => 31,
        C::QueryRates => 32,
        C::QueryRate(_) => 33,
        C::StorePreset(_) => 34,
        C::SetSpeed(..) => 35,
        C::QueryStoredPreset(_) => 36,
        C::TiltDown => 37,
        C::TiltStop => 38,
        C::TiltUp => 39,
        C::SetVectorMode(_) => 40,
        C::CameraOn => 41,
        C::CameraOff => 42,
        C::FocusSpeed(_) => 43,
        C::AutoFocusOn => 44,
        C::FocusFar => 45,
        C::FocusNear => 46,
        C::FocusStop => 47,
        C::AutoFocusOff => 48,
        C::LensGoTo(_) => 49,
        C::QueryLens => 50,
        C::ZoomSpeed(_) => 51,
        C::DigitalZoom(_) => 52,
        C::ZoomIn => 53,
        C::ZoomOut => 54,
        C::ZoomStop => 55,
        C::AuxConfigure(..) => 56,
        C::AuxTransmit(..) => 57,
        C::AuxReceive(..) => 58,
        C::AuxCount(_) => 59,
        C::AuxFlush(_) => 60,
        C::Extended(..) => 61,
        C::Unknown(_) => 62,
    }
}

/// Number of `Reply` variants.
pub const REPLY_VARIANTS: usize = 19;

/// A distinct index per `Reply` variant (exhaustive).
pub fn reply_index(r: &Reply<'_>) -> usize {
    match r {
        Reply::AwakeStatus(_) => 0,
        Reply::MaxDataRate(_) => 1,
        Reply::Identity(_) => 2,
        Reply::Errors(_) => 3,
        Reply::StatusBits(_) => 4,
        Reply::RateGains(_) => 5,
        Reply::Initialization(_) => 6,
        Reply::Limits(_) => 7,
        Reply::Relays(_) => 8,
        Reply::Accelerations { .. } => 9,
        Reply::Acceleration(_) => 10,
        Reply::Rates { .. } => 11,
        Reply::Rate(_) => 12,
        Reply::VerifyHome(_) => 13,
        Reply::Position(_) => 14,
        Reply::Lens(_) => 15,
        Reply::AuxCount(_) => 16,
        Reply::AuxData(_) => 17,
        Reply::Raw(_) => 18,
    }
}

fn printable_field() -> impl Strategy<Value = &'static [u8]> {
    proptest::collection::vec(0x20u8..=0x7E, 0..=20).prop_map(|mut v| {
        while v.last() == Some(&b' ') {
            v.pop();
        }
        leak(v)
    })
}

/// A command that takes a result, with a result of the kind it expects;
/// every `Reply` variant is produced.
pub fn command_and_reply() -> impl Strategy<Value = (Command<'static>, Reply<'static>)> {
    use Command as C;
    let raw_commands: Vec<Extended> = Extended::ALL
        .iter()
        .copied()
        .filter(|e| e.result_kind() != ResultKind::None)
        .collect();
    let bytes = || proptest::collection::vec(any::<u8>(), 1..=256).prop_map(leak);
    let strategies: Vec<BoxedStrategy<(Command<'static>, Reply<'static>)>> = vec![
        (0u8..=15)
            .prop_map(|b| (C::AwakeStatus, Reply::AwakeStatus(AwakeStatus::new(b).unwrap())))
            .boxed(),
        data_rate()
            .prop_map(|r| (C::QueryMaxDataRate, Reply::MaxDataRate(r)))
            .boxed(),
        (any::<u8>(), any::<[u8; 2]>(), printable_field(), printable_field())
            .prop_map(|(id, rev, name, serial)| {
                (
                    C::Identify,
                    Reply::Identity(Identity::new(id, rev, name, serial).unwrap()),
                )
            })
            .boxed(),
        (any::<u8>(), any::<u8>())
            .prop_map(|(pan, tilt)| (C::QueryErrors, Reply::Errors(ErrorCodes { pan, tilt })))
            .boxed(),
        (any::<u16>(), any::<u16>())
            .prop_map(|(pan, tilt)| (C::QueryStatusBits, Reply::StatusBits(StatusBits { pan, tilt })))
            .boxed(),
        (3u8..=30, 3u8..=30)
            .prop_map(|(p, t)| {
                let g = RateGains {
                    pan: RateGain::new(p).unwrap(),
                    tilt: RateGain::new(t).unwrap(),
                };
                (C::QueryRateGains, Reply::RateGains(g))
            })
            .boxed(),
        any::<[u16; 4]>()
            .prop_map(|[a, b, c, d]| {
                let r = InitResults {
                    pan_ccw: a,
                    pan_cw: b,
                    tilt_ccw: c,
                    tilt_cw: d,
                };
                (C::Initialize, Reply::Initialization(r))
            })
            .boxed(),
        limits().prop_map(|l| (C::QueryLimits, Reply::Limits(l))).boxed(),
        (0u8..=15).prop_map(|b| (C::QueryRelays, Reply::Relays(b))).boxed(),
        (any::<u16>(), any::<u16>())
            .prop_map(|(p, t)| {
                let r = Reply::Accelerations {
                    pan: Acceleration(p),
                    tilt: Acceleration(t),
                };
                (C::QueryAccelerations, r)
            })
            .boxed(),
        (axis(), any::<u16>())
            .prop_map(|(a, v)| (C::QueryAcceleration(a), Reply::Acceleration(Acceleration(v))))
            .boxed(),
        (any::<u16>(), any::<u16>())
            .prop_map(|(p, t)| {
                (
                    C::QueryRates,
                    Reply::Rates {
                        pan: Rate(p),
                        tilt: Rate(t),
                    },
                )
            })
            .boxed(),
        (axis(), any::<u16>())
            .prop_map(|(a, v)| (C::QueryRate(a), Reply::Rate(Rate(v))))
            .boxed(),
        (0u8..=15, 0u8..=15, 0u8..=15)
            .prop_map(|(l, c, k)| {
                let h = HomeStatus {
                    limit_switches: l,
                    center_switches: c,
                    count_correct: k,
                };
                (C::VerifyHome, Reply::VerifyHome(h))
            })
            .boxed(),
        (
            prop_oneof![
                Just(C::QueryPosition),
                any::<u8>().prop_map(C::QueryPreset),
                any::<u8>().prop_map(C::QueryStoredPreset)
            ],
            position(),
        )
            .prop_map(|(c, p)| (c, Reply::Position(p)))
            .boxed(),
        lens().prop_map(|l| (C::QueryLens, Reply::Lens(l))).boxed(),
        (aux_port(), any::<u16>())
            .prop_map(|(p, n)| (C::AuxCount(p), Reply::AuxCount(n)))
            .boxed(),
        (aux_port(), 1u16..=256, bytes())
            .prop_map(|(p, n, d)| (C::AuxReceive(p, AuxReadLen::new(n).unwrap()), Reply::AuxData(d)))
            .boxed(),
        (
            proptest::sample::select(raw_commands),
            proptest::collection::vec(any::<u8>(), 0..8),
            bytes(),
        )
            .prop_map(|(e, args, d)| (C::Extended(e, leak(args)), Reply::Raw(d)))
            .boxed(),
    ];
    Union::new(strategies)
}

/// A framer event with its borrowed payload copied, for comparing runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Owned {
    Frame {
        dest: Address,
        source: u8,
        payload: Vec<u8>,
    },
    Ack,
    Nak,
    Nic,
    Bad(BadChecksum),
}

impl Owned {
    pub fn of(event: &Event<'_>) -> Self {
        match event {
            Event::Frame(f) => Owned::Frame {
                dest: f.dest,
                source: f.source,
                payload: f.payload().to_vec(),
            },
            Event::Ack => Owned::Ack,
            Event::Nak => Owned::Nak,
            Event::Nic => Owned::Nic,
            Event::BadChecksum(b) => Owned::Bad(*b),
        }
    }

    /// Stream bytes the event accounts for (a bad candidate's bytes are
    /// counted as skipped).
    pub fn wire_len(&self) -> usize {
        match self {
            Owned::Frame { payload, .. } => payload.len() + 7,
            Owned::Ack | Owned::Nak | Owned::Nic => 1,
            Owned::Bad(_) => 0,
        }
    }
}

/// The wire bytes of a frame.
pub fn wire(dest: Address, source: u8, payload: &[u8]) -> Vec<u8> {
    FrameBuf::new(dest, source, payload).unwrap().as_bytes().to_vec()
}

pub fn address() -> impl Strategy<Value = Address> {
    (any::<u8>(), any::<u8>(), any::<u8>()).prop_map(|(g, p, d)| Address::new(g, p, d))
}

/// One valid frame's wire bytes, payload 1..=256 arbitrary bytes.
pub fn frame_bytes() -> impl Strategy<Value = Vec<u8>> {
    (address(), any::<u8>(), proptest::collection::vec(any::<u8>(), 1..=256)).prop_map(|(a, s, p)| wire(a, s, &p))
}

/// A stream of frames, bare ACK/NAK/NIC bytes and noise (0xF8 included).
pub fn stream() -> impl Strategy<Value = Vec<u8>> {
    let piece = prop_oneof![
        4 => (address(), any::<u8>(), proptest::collection::vec(any::<u8>(), 1..=40))
            .prop_map(|(a, s, p)| wire(a, s, &p)),
        1 => frame_bytes(),
        2 => proptest::sample::select(vec![vec![0x06u8], vec![0x15], vec![b'?']]),
        2 => proptest::collection::vec(any::<u8>(), 1..8),
        1 => proptest::collection::vec(proptest::sample::select(vec![0xF8u8, 0x00, 0x06, 0x15, b'?', 0x02]), 1..8),
    ];
    proptest::collection::vec(piece, 0..12).prop_map(|v| v.concat())
}

/// Runs a whole stream through `feed`, then the silence hook.
pub fn feed_all<const N: usize>(framer: &mut Framer<N>, chunks: &[&[u8]]) -> Vec<Owned> {
    let mut out = Vec::new();
    for chunk in chunks {
        framer.feed(chunk, |e| out.push(Owned::of(&e)));
    }
    framer.flush_idle(|e| out.push(Owned::of(&e)));
    out
}
