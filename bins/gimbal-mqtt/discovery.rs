//! Home Assistant MQTT discovery (Home Assistant's "MQTT Discovery":
//! `<discovery_prefix>/<component>/<node_id>/<object_id>/config`,
//! retained): per gimbal one device with pan and tilt `number`s (moving
//! there), a preset `select`, Home and Stop `button`s, pan and tilt
//! `sensor`s, a `binary_sensor` for moving and a `sensor` naming the
//! controller, each available while the door is online and the gimbal
//! answers. Published at every connection and whenever Home Assistant
//! says it is back (`<discovery_prefix>/status` `online`).

use serde_json::{Value, json};

use crate::config::{Config, Gimbal};
use crate::topics::Topics;

/// Each discovery message of gimbal `g`: (topic, retained payload).
pub fn messages(config: &Config, topics: &Topics, g: &Gimbal) -> Vec<(String, Vec<u8>)> {
    let Some(prefix) = &config.discovery_prefix else {
        return Vec::new();
    };
    let node = format!("sagebrush_{}_{}", config.site, g.name);
    let cmd = topics.cmd(&g.name);
    let state = topics.state(&g.name);
    let common = json!({
        "device": {
            "identifiers": [node],
            "name": format!("{} {}", config.site, g.name),
            "manufacturer": "Sagebrush",
            "model": format!("pan-tilt gimbal {}", g.address),
        },
        "origin": { "name": "gimbal-mqtt", "sw_version": env!("CARGO_PKG_VERSION") },
        "availability": [
            { "topic": topics.status(), "payload_available": "online", "payload_not_available": "offline" },
            { "topic": state, "value_template": "{{ 'online' if value_json.online else 'offline' }}" },
        ],
        "availability_mode": "all",
    });
    let number = |axis: &str, (min, max): (f64, f64)| {
        json!({
            "name": format!("{} position", capital(axis)),
            "command_topic": cmd,
            "command_template": format!("{{\"goto\": {{\"{axis}_deg\": {{{{ value }}}}}}}}"),
            "state_topic": state,
            "value_template": format!("{{{{ value_json.{axis}_deg }}}}"),
            "min": min, "max": max, "step": 0.1, "mode": "box",
            "unit_of_measurement": "°",
        })
    };
    let sensor = |axis: &str| {
        json!({
            "name": capital(axis),
            "state_topic": state,
            "value_template": format!("{{{{ value_json.{axis}_deg }}}}"),
            "unit_of_measurement": "°",
            "state_class": "measurement",
        })
    };
    let options: Vec<String> = g.presets.iter().map(|n| format!("Preset {n}")).collect();
    let entities = [
        ("number", "pan", number("pan", g.pan_deg)),
        ("number", "tilt", number("tilt", g.tilt_deg)),
        (
            "select",
            "preset",
            json!({
                "name": "Preset",
                "command_topic": cmd,
                "command_template": "{\"preset\": {\"recall\": {{ value | replace('Preset ', '') | int }}}}",
                "options": options,
            }),
        ),
        (
            "button",
            "home",
            json!({ "name": "Home", "command_topic": cmd, "payload_press": "{\"home\": true}" }),
        ),
        (
            "button",
            "stop",
            json!({ "name": "Stop", "command_topic": cmd, "payload_press": "{\"stop\": true}" }),
        ),
        ("sensor", "pan_angle", sensor("pan")),
        ("sensor", "tilt_angle", sensor("tilt")),
        (
            "binary_sensor",
            "moving",
            json!({
                "name": "Moving",
                "state_topic": state,
                "value_template": "{{ 'ON' if value_json.moving else 'OFF' }}",
                "device_class": "moving",
            }),
        ),
        (
            "sensor",
            "controller",
            json!({
                "name": "Controller",
                "state_topic": state,
                "value_template": "{{ value_json.controller if value_json.controller else 'nobody' }}",
            }),
        ),
    ];
    entities
        .into_iter()
        .map(|(component, object, mut entity)| {
            merge(&mut entity, &common);
            entity["unique_id"] = json!(format!("{node}_{object}"));
            (
                format!("{prefix}/{component}/{node}/{object}/config"),
                entity.to_string().into_bytes(),
            )
        })
        .collect()
}

fn capital(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

fn merge(into: &mut Value, from: &Value) {
    if let (Some(into), Some(from)) = (into.as_object_mut(), from.as_object()) {
        for (k, v) in from {
            into.insert(k.clone(), v.clone());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn one_device_with_the_entities_of_the_issue() {
        let text = "gcud = \"127.0.0.1:4001\"\nsite = \"north\"\n[broker]\nurl = \"mqtt://127.0.0.1\"\n\
                    [[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\npresets = [1, 2]\n";
        let config = crate::config::parse(Path::new("m.toml"), text).unwrap();
        let topics = Topics::new(&config);
        let m = messages(&config, &topics, &config.gimbals[0]);
        let names: Vec<&str> = m.iter().map(|(t, _)| t.as_str()).collect();
        assert_eq!(
            names,
            [
                "homeassistant/number/sagebrush_north_mast-1/pan/config",
                "homeassistant/number/sagebrush_north_mast-1/tilt/config",
                "homeassistant/select/sagebrush_north_mast-1/preset/config",
                "homeassistant/button/sagebrush_north_mast-1/home/config",
                "homeassistant/button/sagebrush_north_mast-1/stop/config",
                "homeassistant/sensor/sagebrush_north_mast-1/pan_angle/config",
                "homeassistant/sensor/sagebrush_north_mast-1/tilt_angle/config",
                "homeassistant/binary_sensor/sagebrush_north_mast-1/moving/config",
                "homeassistant/sensor/sagebrush_north_mast-1/controller/config",
            ]
        );
        let pan: Value = serde_json::from_slice(&m[0].1).unwrap();
        assert_eq!(pan["command_topic"], "sagebrush/north/mast-1/cmd");
        assert_eq!(pan["command_template"], "{\"goto\": {\"pan_deg\": {{ value }}}}");
        assert_eq!(pan["availability"][0]["topic"], "sagebrush/north/status");
        let select: Value = serde_json::from_slice(&m[2].1).unwrap();
        assert_eq!(select["options"], json!(["Preset 1", "Preset 2"]));
        let off = text.replace("site =", "discovery_prefix = \"\"\nsite =");
        let config = crate::config::parse(Path::new("m.toml"), &off).unwrap();
        assert!(messages(&config, &topics, &config.gimbals[0]).is_empty());
    }
}
