//! `[control]`, `[[gimbal]]` and `[[tour]]`: how gcud governs the gimbals
//! on its own ports (ARCHITECTURE "Governance"), validated into the router
//! core's [`Governance`]. Angles are degrees in the file and hundredths of
//! a degree in the core (rounded), times seconds in the file and
//! milliseconds in the core. What the core checks itself
//! ([`Governance::validate`]: a tour step past a limit or into a zone) is
//! reported at the step's place in the file.

use std::ops::Range;

use sagebrush_gcu::{GimbalRules, Governance, Park, Span, TourConfig, TourStep, TourTarget, Zone};
use sagebrush_protocol::{Address, Angle, Position};
use sagebrush_service::config_file::{Int, Millis, Source, checked};
use serde::{Deserialize, Deserializer, Serialize};
use toml::Spanned;

use super::{ConfigError, Port};

/// `[control]`, as written and as validated.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ControlSection {
    /// A link keeps control of a gimbal this long after its last command
    /// that moved or changed it: 100 ms to 1 hour.
    #[serde(default)]
    pub hold_ms: Millis<100, 3_600_000, { sagebrush_gcu::HOLD_MS as i64 }>,
    /// The lowest link priority that may start or stop gcud's tours
    /// (`~T`); default: the highest priority of any `[[link]]`.
    pub tours_min_priority: Option<Int<u8, 0, { sagebrush_gcu::MAX_PRIORITY as i64 }>>,
}

/// The longest park delay or dwell, seconds (a day).
const MAX_SECONDS: f64 = 86_400.0;

/// One name of `allow = [...]`: a command the governance refuses on a
/// governed gimbal (its row's mount effect is unbounded, identity or
/// dynamics), by its rev 1.9 name (`*mp`), its wire bytes (`IX`, `LC`,
/// `HP`) or its row's script name (`set_device_id`, `set_limits`,
/// `unknown`).
fn allowed(c: &Source<'_>, name: &Spanned<String>, key: &str) -> Result<String, ConfigError> {
    use sagebrush_protocol::{Command, Extended, Row};
    let text = name.get_ref().as_str();
    let named = Extended::ALL
        .iter()
        .find(|e| e.name() == text)
        .map(|e| Some(e.mount()))
        .or_else(|| {
            Command::FIXED
                .iter()
                .find(|(wire, _)| *wire == text.as_bytes())
                .map(|(_, command)| Some(command.mount()))
        })
        .or_else(|| Row::ALL.iter().any(|r| r.script_name() == text).then_some(None));
    match named {
        Some(Some(mount)) if !mount.is_ungoverned() => Err(c.at(
            name.span(),
            key,
            format!(
                "{text} is never refused for what it does (only control decides it): allow has nothing to let through"
            ),
        )),
        Some(_) => Ok(text.to_owned()),
        None => Err(c.at(
            name.span(),
            key,
            format!(
                "expected a command's rev 1.9 name (*mp), wire bytes (IX, LC, HP) or script name \
                 (set_device_id, set_limits, unknown), found {text:?}"
            ),
        )),
    }
}

/// A time in seconds, `0..=86400`, fractions allowed, in milliseconds;
/// 0 where the key is absent.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(super) struct Seconds {
    ms: u64,
}

impl<'de> Deserialize<'de> for Seconds {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (ms, _) = checked(d, |s: &f64| {
            if (0.0..=MAX_SECONDS).contains(s) {
                Ok((s * 1000.0).round() as u64)
            } else {
                Err(format!("expected seconds 0..={MAX_SECONDS}, found {s}"))
            }
        })?;
        Ok(Self { ms })
    }
}

/// `park = { preset = N, after_s = S }`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ParkSection {
    preset: Int<u8, 0, 255>,
    after_s: Seconds,
}

/// `[[gimbal.keep_out]]`: a pan/tilt rectangle no motion may enter.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct KeepOutSection {
    pan_deg: Spanned<Vec<f64>>,
    tilt_deg: Spanned<Vec<f64>>,
}

/// `[[gimbal]]`: the rules of one gimbal on a port of this GCU, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GimbalSection {
    address: Spanned<String>,
    pan_limits_deg: Option<Spanned<Vec<f64>>>,
    tilt_limits_deg: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    keep_out: Vec<KeepOutSection>,
    park: Option<ParkSection>,
    slew_rate_dps: Option<Spanned<Vec<f64>>>,
    acceleration_dps2: Option<Spanned<Vec<f64>>>,
    allow: Option<Spanned<Vec<Spanned<String>>>>,
}

/// One of `steps = [ ... ]`: a preset or a position, and the dwell.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct StepSection {
    preset: Option<Int<u8, 0, 255>>,
    pan_deg: Option<Spanned<f64>>,
    tilt_deg: Option<Spanned<f64>>,
    #[serde(default)]
    dwell_s: Seconds,
}

/// `[[tour]]`, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct TourSection {
    name: Spanned<String>,
    address: Spanned<String>,
    steps: Spanned<Vec<Spanned<StepSection>>>,
}

/// The largest angle a position carries (Table 15), degrees.
const MAX_DEGREES: f64 = 327.67;

fn centi(degrees: f64) -> i32 {
    (degrees * 100.0).round() as i32
}

/// `[LOW, HIGH]` degrees, `LOW < HIGH`, within ±327.67, as a [`Span`].
fn span(c: &Source<'_>, v: &Spanned<Vec<f64>>, key: &str) -> Result<Span, ConfigError> {
    match v.get_ref().as_slice() {
        [lo, hi] if lo < hi && *lo >= -MAX_DEGREES && *hi <= MAX_DEGREES => Ok(Span::new(centi(*lo), centi(*hi))),
        _ => Err(c.at(
            v.span(),
            key,
            "expected [LOW, HIGH] degrees, LOW < HIGH, within -327.67..=327.67 (Table 15)",
        )),
    }
}

/// `[PAN, TILT]` of a rate (per second) or acceleration (per second
/// squared) in degrees, each above 0 and at most 655.35 (Table 12), in hundredths.
fn per_axis(c: &Source<'_>, v: &Spanned<Vec<f64>>, key: &str, unit: &str) -> Result<[u32; 2], ConfigError> {
    let hundredths = |x: f64| (x > 0.0 && x <= 655.35).then(|| ((x * 100.0).round() as u32).max(1));
    if let [pan, tilt] = v.get_ref().as_slice() {
        if let (Some(p), Some(t)) = (hundredths(*pan), hundredths(*tilt)) {
            return Ok([p, t]);
        }
    }
    Err(c.at(
        v.span(),
        key,
        format!("expected [PAN, TILT] in {unit}, each above 0 and at most 655.35 (Table 12)"),
    ))
}

/// One angle of a position, degrees within ±327.67.
fn angle(c: &Source<'_>, v: &Spanned<f64>, key: &str) -> Result<Angle, ConfigError> {
    let d = *v.get_ref();
    match (-MAX_DEGREES..=MAX_DEGREES).contains(&d) {
        true => Ok(Angle(centi(d) as i16)),
        false => Err(c.at(
            v.span(),
            key,
            format!("expected degrees within -327.67..=327.67 (Table 15), found {d}"),
        )),
    }
}

/// A gimbal's address `G.P.D`: one gimbal, of this GCU's group, on a configured port.
fn local_gimbal(
    c: &Source<'_>,
    v: &Spanned<String>,
    key: &str,
    group: u8,
    ports: &[Port],
) -> Result<Address, ConfigError> {
    let address = c.gimbal_address(v, key)?;
    if address.group != group {
        return Err(c.at(
            v.span(),
            key,
            format!(
                "group {} is not this GCU's ({group}): gcud governs the gimbals on its own ports only",
                address.group
            ),
        ));
    }
    if !ports.iter().any(|p| p.id == address.port) {
        return Err(c.at(v.span(), key, format!("no [[port]] has id {}", address.port)));
    }
    Ok(address)
}

/// Where each gimbal and tour is in the file, to place what the core refuses.
struct Places {
    gimbals: Vec<((u8, u8), Range<usize>)>,
    /// Each tour's name, its name's span, and each step's span.
    tours: Vec<(String, Range<usize>, Vec<Range<usize>>)>,
}

/// `[control]`, every `[[gimbal]]` and every `[[tour]]`, validated.
pub(super) fn validate(
    c: &Source<'_>,
    control: &ControlSection,
    raw_gimbals: &[GimbalSection],
    raw_tours: &[TourSection],
    group: u8,
    ports: &[Port],
) -> Result<Governance, ConfigError> {
    let mut places = Places {
        gimbals: Vec::new(),
        tours: Vec::new(),
    };
    let mut gimbals = Vec::with_capacity(raw_gimbals.len());
    for (i, g) in raw_gimbals.iter().enumerate() {
        let key = format!("gimbal[{i}]");
        let at = local_gimbal(c, &g.address, &format!("{key}.address"), group, ports)?;
        if let Some((_, first)) = places.gimbals.iter().find(|(a, _)| *a == (at.port, at.device)) {
            let line = c.at(first.clone(), "", "").line;
            return Err(c.at(
                g.address.span(),
                format!("{key}.address"),
                format!("gimbal {at} already has a [[gimbal]] (line {line}): one per gimbal"),
            ));
        }
        places.gimbals.push(((at.port, at.device), g.address.span()));
        let mut rules = GimbalRules::new(at.port, at.device);
        rules.pan_limits = g
            .pan_limits_deg
            .as_ref()
            .map(|v| span(c, v, &format!("{key}.pan_limits_deg")))
            .transpose()?;
        rules.tilt_limits = g
            .tilt_limits_deg
            .as_ref()
            .map(|v| span(c, v, &format!("{key}.tilt_limits_deg")))
            .transpose()?;
        for (j, zone) in g.keep_out.iter().enumerate() {
            rules.keep_out.push(Zone {
                pan: span(c, &zone.pan_deg, &format!("{key}.keep_out[{j}].pan_deg"))?,
                tilt: span(c, &zone.tilt_deg, &format!("{key}.keep_out[{j}].tilt_deg"))?,
            });
        }
        rules.park = g.park.as_ref().map(|p| Park {
            preset: p.preset.get(),
            after: p.after_s.ms,
        });
        rules.slew_rate = g
            .slew_rate_dps
            .as_ref()
            .map(|v| per_axis(c, v, &format!("{key}.slew_rate_dps"), "degrees per second"))
            .transpose()?;
        rules.acceleration = g
            .acceleration_dps2
            .as_ref()
            .map(|v| per_axis(c, v, &format!("{key}.acceleration_dps2"), "degrees per second squared"))
            .transpose()?;
        for (j, name) in g.allow.iter().flat_map(|l| l.get_ref().iter()).enumerate() {
            rules.allow.push(allowed(c, name, &format!("{key}.allow[{j}]"))?);
        }
        gimbals.push(rules);
    }
    let mut tours = Vec::with_capacity(raw_tours.len());
    for (i, t) in raw_tours.iter().enumerate() {
        let key = format!("tour[{i}]");
        let name = t.name.get_ref();
        if !sagebrush_protocol::gcu::valid_name(name.as_bytes()) {
            return Err(c.at(
                t.name.span(),
                format!("{key}.name"),
                format!(
                    "expected 1..=32 of A-Z a-z 0-9 _ - (the name travels in GCU commands, `gimbalctl tour start NAME`), found {name:?}"
                ),
            ));
        }
        if let Some((_, first, _)) = places.tours.iter().find(|(n, ..)| n == name) {
            let line = c.at(first.clone(), "", "").line;
            return Err(c.at(
                t.name.span(),
                format!("{key}.name"),
                format!("tour {name:?} is already configured (line {line}): names are unique"),
            ));
        }
        let at = local_gimbal(c, &t.address, &format!("{key}.address"), group, ports)?;
        if t.steps.get_ref().is_empty() {
            return Err(c.at(t.steps.span(), format!("{key}.steps"), "expected at least one step"));
        }
        let steps = tour_steps(c, t, &key)?;
        places.tours.push((
            name.clone(),
            t.name.span(),
            t.steps.get_ref().iter().map(Spanned::span).collect(),
        ));
        tours.push(TourConfig {
            name: name.clone(),
            port: at.port,
            device: at.device,
            steps,
        });
    }
    let governance = Governance {
        hold: control.hold_ms.get(),
        gimbals,
        tours,
        tours_min_priority: control.tours_min_priority.as_ref().map(Int::get),
        principals: Vec::new(),
    };
    let port_ids: Vec<u8> = ports.iter().map(|p| p.router.id).collect();
    match governance.validate(&port_ids) {
        Ok(()) => Ok(governance),
        Err(e) => Err(placed(c, &places, e.to_string())),
    }
}

/// A tour's steps, each a preset or a position with its dwell.
fn tour_steps(c: &Source<'_>, t: &TourSection, key: &str) -> Result<Vec<TourStep>, ConfigError> {
    let mut steps = Vec::with_capacity(t.steps.get_ref().len());
    for (n, s) in t.steps.get_ref().iter().enumerate() {
        let skey = format!("{key}.steps[{n}]");
        let step = s.get_ref();
        let to = match (&step.preset, &step.pan_deg, &step.tilt_deg) {
            (Some(p), None, None) => TourTarget::Preset(p.get()),
            (None, Some(pan), Some(tilt)) => TourTarget::Position(Position::new(
                angle(c, pan, &format!("{skey}.pan_deg"))?,
                angle(c, tilt, &format!("{skey}.tilt_deg"))?,
            )),
            _ => {
                return Err(c.at(
                    s.span(),
                    skey,
                    "expected { preset = N, dwell_s = S } or { pan_deg = P, tilt_deg = T, dwell_s = S }",
                ));
            }
        };
        steps.push(TourStep {
            to,
            dwell: step.dwell_s.ms,
        });
    }
    Ok(steps)
}

/// The core's refusal at the place it names: `tour NAME: step N ...` at
/// that step, `tour NAME: ...` at its name, `gimbal P.D: ...` at its address.
fn placed(c: &Source<'_>, places: &Places, message: String) -> ConfigError {
    if let Some(rest) = message.strip_prefix("tour ") {
        let name = rest.split(':').next().unwrap_or_default();
        if let Some((i, (_, name_span, steps))) = places.tours.iter().enumerate().find(|(_, (n, ..))| n == name) {
            let step = rest
                .split(": step ")
                .nth(1)
                .and_then(|s| s.split(' ').next())
                .and_then(|n| n.parse::<usize>().ok())
                .and_then(|n| n.checked_sub(1));
            return match step.and_then(|n| steps.get(n).map(|span| (n, span))) {
                Some((n, span)) => c.at(span.clone(), format!("tour[{i}].steps[{n}]"), message),
                None => c.at(name_span.clone(), format!("tour[{i}].name"), message),
            };
        }
    }
    if let Some(rest) = message.strip_prefix("gimbal ") {
        let at = rest.split(':').next().unwrap_or_default();
        let found = places
            .gimbals
            .iter()
            .enumerate()
            .find(|(_, ((p, d), _))| format!("{p}.{d}") == at);
        if let Some((i, (_, span))) = found {
            return c.at(span.clone(), format!("gimbal[{i}].address"), message);
        }
    }
    c.at(0..0, "", message)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::config::{ConfigError, parse};

    const BASE: &str = "[gcu]\ngroup = 5\n[[port]]\nid = 1\nsimulate = [1, 2]\n\
                        [[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n";

    fn err(extra: &str) -> ConfigError {
        parse(Path::new("t.toml"), &format!("{BASE}{extra}")).expect_err("refused")
    }

    #[test]
    fn the_issues_example_is_read_in_hundredths_and_milliseconds() {
        let text = format!(
            "{BASE}[control]\nhold_ms = 2500\n\
             [[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\ntilt_limits_deg = [-30, 90.004]\n\
             park = {{ preset = 1, after_s = 300 }}\nslew_rate_dps = [60, 30.5]\nacceleration_dps2 = [120, 60]\n\
             [[gimbal.keep_out]]\npan_deg = [40.0, 60.0]\ntilt_deg = [-30.0, 10.0]\n\
             [[tour]]\nname = \"perimeter\"\naddress = \"5.1.1\"\n\
             steps = [ {{ preset = 1, dwell_s = 10 }}, {{ pan_deg = -45.0, tilt_deg = -10.0, dwell_s = 0.5 }} ]\n"
        );
        let c = parse(Path::new("t.toml"), &text).expect("valid");
        let g = &c.governance;
        assert_eq!(g.hold, 2500);
        let rules = &g.gimbals[0];
        assert_eq!((rules.port, rules.device), (1, 1));
        assert_eq!(rules.pan_limits, Some(sagebrush_gcu::Span::new(-17000, 17000)));
        assert_eq!(rules.tilt_limits, Some(sagebrush_gcu::Span::new(-3000, 9000)));
        assert_eq!(rules.keep_out[0].pan, sagebrush_gcu::Span::new(4000, 6000));
        assert_eq!(
            rules.park,
            Some(sagebrush_gcu::Park {
                preset: 1,
                after: 300_000
            })
        );
        assert_eq!(rules.slew_rate, Some([6000, 3050]));
        assert_eq!(rules.acceleration, Some([12000, 6000]));
        let tour = &g.tours[0];
        assert_eq!(tour.name, "perimeter");
        assert_eq!(tour.steps[0].to, sagebrush_gcu::TourTarget::Preset(1));
        assert_eq!(tour.steps[0].dwell, 10_000);
        assert_eq!(tour.steps[1].dwell, 500);
        let defaults = parse(Path::new("t.toml"), BASE).expect("valid");
        assert_eq!(
            defaults.governance,
            sagebrush_gcu::Governance {
                // Tours from the highest link's priority up (the one link's default 50).
                tours_min_priority: Some(50),
                ..sagebrush_gcu::Governance::default()
            }
        );
        assert_eq!(defaults.governance.hold, 10_000);
    }

    /// `allow`, `tours_min_priority` and `may_read_rules` (ARCHITECTURE "Governance").
    #[test]
    fn allow_names_commands_the_governance_refuses_and_nothing_else() {
        let text = format!(
            "{BASE}[control]\ntours_min_priority = 70\n\
             [[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-90, 90]\nallow = [\"*mp\", \"IX\", \"set_device_id\", \"unknown\"]\n"
        );
        let c = parse(Path::new("t.toml"), &text).expect("valid");
        assert_eq!(c.governance.tours_min_priority, Some(70));
        assert_eq!(c.governance.gimbals[0].allow, ["*mp", "IX", "set_device_id", "unknown"]);
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\nallow = [\"PR\"]\n");
        assert_eq!(e.key, "gimbal[0].allow[0]", "{e}");
        assert!(e.to_string().contains("never refused"), "{e}");
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\nallow = [\"*zz\"]\n");
        assert!(e.to_string().contains("found \"*zz\""), "{e}");
        // Rules are read on loopback by default, elsewhere only when said.
        let c = parse(Path::new("t.toml"), BASE).expect("valid");
        assert!(c.links[0].may_read_rules);
        let remote = BASE.replace("127.0.0.1:0", "0.0.0.0:0");
        let c = parse(Path::new("t.toml"), &remote).expect("valid");
        assert!(!c.links[0].may_read_rules);
        let c = parse(Path::new("t.toml"), &format!("{remote}may_read_rules = true\n")).expect("valid");
        assert!(c.links[0].may_read_rules);
    }

    #[test]
    fn every_refusal_names_its_place_and_key() {
        let e = err("[[gimbal]]\naddress = \"6.1.1\"\n");
        assert_eq!((e.key.as_str(), e.line), ("gimbal[0].address", 11), "{e}");
        assert!(e.message.contains("not this GCU's (5)"), "{e}");
        let e = err("[[gimbal]]\naddress = \"5.2.1\"\n");
        assert!(e.message.contains("no [[port]] has id 2"), "{e}");
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\n[[gimbal]]\naddress = \"5.1.1\"\n");
        assert_eq!((e.key.as_str(), e.line), ("gimbal[1].address", 13), "{e}");
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [10, -10]\n");
        assert_eq!(
            (e.key.as_str(), e.line, e.column),
            ("gimbal[0].pan_limits_deg", 12, 18),
            "{e}"
        );
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\n[[gimbal.keep_out]]\npan_deg = [1, 2]\ntilt_deg = [1]\n");
        assert_eq!(e.key, "gimbal[0].keep_out[0].tilt_deg", "{e}");
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\npark = { preset = 1, after_s = -1 }\n");
        assert_eq!(e.key, "gimbal[0].park.after_s", "{e}");
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\npark = { preset = 1 }\n");
        assert!(e.message.contains("after_s"), "{e}");
        let e = err("[[gimbal]]\naddress = \"5.1.1\"\nslew_rate_dps = [0, 10]\n");
        assert_eq!(e.key, "gimbal[0].slew_rate_dps", "{e}");
        let e = err("[control]\nhold_ms = 5\n");
        assert_eq!(e.key, "control.hold_ms", "{e}");
        let e = err("[[tour]]\nname = \"a b\"\naddress = \"5.1.1\"\nsteps = [ { preset = 1 } ]\n");
        assert_eq!(e.key, "tour[0].name", "{e}");
        let e = err("[[tour]]\nname = \"t\"\naddress = \"5.1.1\"\nsteps = []\n");
        assert_eq!(e.key, "tour[0].steps", "{e}");
        let e = err("[[tour]]\nname = \"t\"\naddress = \"5.1.1\"\nsteps = [ { preset = 1 }, { pan_deg = 3 } ]\n");
        assert_eq!((e.key.as_str(), e.line), ("tour[0].steps[1]", 13), "{e}");
        let e = err(
            "[[tour]]\nname = \"t\"\naddress = \"5.1.1\"\nsteps = [ { preset = 1 } ]\n[[tour]]\nname = \"t\"\naddress = \"5.1.2\"\nsteps = [ { preset = 1 } ]\n",
        );
        assert_eq!((e.key.as_str(), e.line), ("tour[1].name", 15), "{e}");
    }

    #[test]
    fn link_names_travel_in_gcu_commands_and_priorities_are_0_to_100() {
        let link = |name: &str, extra: &str| {
            format!(
                "[gcu]\ngroup = 5\n[[link]]\nname = \"{name}\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n{extra}"
            )
        };
        let e = parse(Path::new("t.toml"), &link("north mast", "")).expect_err("refused");
        assert_eq!((e.key.as_str(), e.line), ("link[0].name", 4), "{e}");
        assert!(e.message.contains("1..=32 of A-Z a-z 0-9 _ -"), "{e}");
        let e = parse(Path::new("t.toml"), &link("ops", "priority = 101\n")).expect_err("refused");
        assert_eq!(
            e.to_string(),
            "t.toml:7:12: link[0].priority: expected an integer 0..=100, found 101"
        );
        let c = parse(Path::new("t.toml"), &link("ops", "")).expect("valid");
        assert_eq!(c.links[0].priority, 50);
        let lc = c.links[0].router();
        assert_eq!((lc.name.as_deref(), lc.priority), (Some("ops"), 50));
        let c = parse(Path::new("t.toml"), &link("ops", "priority = 80\n")).expect("valid");
        assert_eq!(c.links[0].router().priority, 80);
    }

    #[test]
    fn a_tour_step_into_a_zone_or_past_a_limit_is_refused_at_the_step() {
        let zone = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-90, 90]\n\
                    [[gimbal.keep_out]]\npan_deg = [40, 60]\ntilt_deg = [-30, 10]\n";
        let e = err(&format!(
            "{zone}[[tour]]\nname = \"t\"\naddress = \"5.1.1\"\nsteps = [\n  {{ preset = 1 }},\n  {{ pan_deg = 45, tilt_deg = -10 }},\n]\n"
        ));
        assert_eq!((e.key.as_str(), e.line, e.column), ("tour[0].steps[1]", 21, 3), "{e}");
        assert!(e.message.contains("keep-out zone"), "{e}");
        let e = err(&format!(
            "{zone}[[tour]]\nname = \"t\"\naddress = \"5.1.1\"\nsteps = [ {{ pan_deg = 95, tilt_deg = 0 }} ]\n"
        ));
        assert_eq!(e.key, "tour[0].steps[0]", "{e}");
        assert!(e.message.contains("travel limits"), "{e}");
        // Around the zone: allowed.
        parse(
            Path::new("t.toml"),
            &format!(
                "{BASE}{zone}[[tour]]\nname = \"t\"\naddress = \"5.1.1\"\nsteps = [ {{ pan_deg = 30, tilt_deg = 20 }}, {{ pan_deg = 70, tilt_deg = 20 }} ]\n"
            ),
        )
        .expect("a path above the zone");
    }
}
