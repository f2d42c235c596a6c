use super::*;
use base64::Engine;
use proptest::prelude::*;
use sha1::{Digest, Sha1};

/// A device whose gcud is a closed port on loopback: every gimbal
/// command fails at once, as when gcud is down.
fn device(rt: &tokio::runtime::Runtime) -> Device {
    let text = r#"
gcud = "127.0.0.1:9"
[discovery]
enabled = false
[[user]]
name = "admin"
password = "pw"
role = "administrator"
[[gimbal]]
name = "g"
address = "5.1.1"
listen = "127.0.0.1:0"
"#;
    let config = crate::config::parse(std::path::Path::new("t.toml"), text).unwrap();
    // The gimbal's session runs on `rt`, where the test blocks: its gcud
    // (the discard port) refuses, so every command fails at once.
    let _rt = rt.enter();
    Device::new(
        Gimbal::new(
            config.gimbals[0].clone(),
            &config,
            &sagebrush_client::door::DoorSessions::new(&config.link, config.poll),
        ),
        Arc::new(Authenticator::new(config.users.clone())),
        Arc::new(Presets::load(None).unwrap()),
        DoorMetrics::new("gimbal-onvif", Vec::new()),
    )
}

/// An envelope signed for `admin` around `body`, with a fresh nonce.
fn signed(body: &str, nonce: u64) -> String {
    let created = args::utc(OffsetDateTime::now_utc());
    let mut h = Sha1::new();
    h.update(nonce.to_be_bytes());
    h.update(created.as_bytes());
    h.update(b"pw");
    let b64 = base64::engine::general_purpose::STANDARD;
    format!(
        r#"<s:Envelope xmlns:s="{}"><s:Header><Security><UsernameToken><Username>admin</Username><Password Type="{}">{}</Password><Nonce>{}</Nonce><Created>{created}</Created></UsernameToken></Security></s:Header><s:Body>{body}</s:Body></s:Envelope>"#,
        soap::NS_SOAP,
        crate::auth::PASSWORD_DIGEST,
        b64.encode(h.finalize()),
        b64.encode(nonce.to_be_bytes())
    )
}

const ORIGIN: Origin<'static> = Origin {
    scheme: "http",
    host: "h:1",
    local: std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST),
    uri: "/onvif/device_service",
    authorization: None,
};

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Any bytes: a fault, never a panic.
    #[test]
    fn any_body_is_answered_without_panicking(body in proptest::collection::vec(any::<u8>(), 0..1024)) {
        let rt = runtime();
        let d = device(&rt);
        prop_assert!(rt.block_on(d.handle(&body, &ORIGIN)).result.is_err());
    }

    /// Any operation of the three services, with any arguments, signed:
    /// a response or a fault, never a panic.
    #[test]
    fn any_signed_operation_is_answered_without_panicking(
        service in prop::sample::select(vec![NS_DEVICE, NS_MEDIA, NS_PTZ]),
        op in prop::sample::select(vec![
            "GetStatus", "ContinuousMove", "AbsoluteMove", "RelativeMove", "Stop", "SetPreset",
            "GotoPreset", "RemovePreset", "GetProfile", "GetStreamUri", "GetNode",
            "GetConfigurationOptions", "GetDeviceInformation", "SetHomePosition", "Reboot", "SetConfiguration",
            "GetCompatibleConfigurations", "CreateProfile", "GetVideoSources",
        ]),
        token in prop::sample::select(vec!["profile1", "ptznode1", "ptzconfig1", "0", "300", "", "x"]),
        x in "[-+0-9.eEn]{0,8}",
        timeout in "P?T?[0-9.]{0,6}[SMHD]?",
        nonce in any::<u64>(),
    ) {
        let body = format!(
            r#"<{op} xmlns="{service}"><ProfileToken>{token}</ProfileToken><NodeToken>{token}</NodeToken><ConfigurationToken>{token}</ConfigurationToken><PresetToken>{token}</PresetToken><Velocity><PanTilt x="{x}" y="{x}"/></Velocity><Position><PanTilt x="{x}" y="0"/></Position><Translation><PanTilt x="{x}"/></Translation><Timeout>{timeout}</Timeout><PTZConfiguration token="{token}"><DefaultPTZTimeout>{timeout}</DefaultPTZTimeout><DefaultRelativePanTiltTranslationSpace>{x}</DefaultRelativePanTiltTranslationSpace></PTZConfiguration></{op}>"#
        );
        let rt = runtime();
        let d = device(&rt);
        let _ = rt.block_on(d.handle(signed(&body, nonce).as_bytes(), &ORIGIN));
    }
}

#[test]
fn roles_and_scopes() {
    assert_eq!(needed_role("GetStatus"), Role::User);
    assert_eq!(needed_role("ContinuousMove"), Role::Operator);
    assert_eq!(needed_role("SetHomePosition"), Role::Administrator);
    assert_eq!(needed_role("Reboot"), Role::Administrator);
    assert_eq!(scope_text("mast 1/a"), "mast%201%2Fa");
}

#[test]
fn a_soap_1_1_request_is_answered_in_soap_1_1_and_dispatched_on_its_body() {
    let rt = runtime();
    let d = device(&rt);
    let clock = format!(
        r#"<e:Envelope xmlns:e="{}"><e:Body><GetSystemDateAndTime xmlns="{NS_DEVICE}"/></e:Body></e:Envelope>"#,
        soap::NS_SOAP11
    );
    let answer = rt.block_on(d.handle(clock.as_bytes(), &ORIGIN));
    assert_eq!(answer.version, Version::Soap11);
    let doc = soap::parse(answer.result.unwrap().as_bytes()).unwrap();
    assert_eq!(doc.ns, soap::NS_SOAP11);
    assert!(doc.path(&["Body", "GetSystemDateAndTimeResponse"]).is_some());
    // Signed, in SOAP 1.1: CreateProfile gets the MaxNVTProfiles fault.
    let create = signed(
        &format!(r#"<CreateProfile xmlns="{NS_MEDIA}"><Name>x</Name></CreateProfile>"#),
        7,
    )
    .replace(soap::NS_SOAP, soap::NS_SOAP11);
    let answer = rt.block_on(d.handle(create.as_bytes(), &ORIGIN));
    assert_eq!(answer.version, Version::Soap11);
    assert_eq!(
        answer.result.unwrap_err().subcodes,
        ["ter:Action", "ter:MaxNVTProfiles"]
    );
}

#[test]
fn set_configuration_changes_what_it_may_and_refuses_the_rest() {
    let rt = runtime();
    let d = device(&rt);
    let set = |inner: &str, nonce: u64| {
        let body = format!(
            r#"<SetConfiguration xmlns="{NS_PTZ}"><PTZConfiguration token="ptzconfig1">{inner}</PTZConfiguration><ForcePersistence>true</ForcePersistence></SetConfiguration>"#
        );
        rt.block_on(d.handle(signed(&body, nonce).as_bytes(), &ORIGIN)).result
    };
    assert!(
        set(
            "<NodeToken>ptznode1</NodeToken><DefaultPTZTimeout>PT5S</DefaultPTZTimeout>",
            1
        )
        .is_ok()
    );
    assert_eq!(d.settings().timeout, Duration::from_secs(5));
    for (inner, nonce) in [
        ("<DefaultPTZTimeout>PT11S</DefaultPTZTimeout>", 2),
        ("<NodeToken>other</NodeToken>", 3),
        (
            &format!(
                "<DefaultRelativePanTiltTranslationSpace>{}</DefaultRelativePanTiltTranslationSpace>",
                spaces::FOV_SPACE
            )[..],
            4,
        ),
        ("<Name>renamed</Name>", 5),
        (
            "<PanTiltLimits><Range><XRange><Min>-0.5</Min><Max>1</Max></XRange></Range></PanTiltLimits>",
            6,
        ),
    ] {
        let fault = set(inner, nonce).unwrap_err();
        assert_eq!(
            fault.subcodes,
            ["ter:InvalidArgVal", "ter:ConfigModify"],
            "{inner}: {}",
            fault.reason
        );
    }
    assert_eq!(
        d.settings().timeout,
        Duration::from_secs(5),
        "a refused change changes nothing"
    );
    assert_eq!(d.settings().relative, spaces::Translation::Generic);
}
