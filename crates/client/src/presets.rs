//! The names of the gimbals' own presets (`Snn`/`Pnn`, 0..=255, the
//! positions are kept by the gimbal), as gimbal-onvif and gimbal-web keep them: a small TOML state file, rewritten
//! whole (to a temporary file, then renamed) at every change, so that names
//! survive a restart and a crash never leaves half a file.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Mutex;

use serde::{Deserialize, Serialize};

/// Per gimbal name: preset number -> name.
#[derive(Debug, Default, Clone, PartialEq, Serialize, Deserialize)]
struct State {
    #[serde(default)]
    gimbal: BTreeMap<String, BTreeMap<String, String>>,
}

#[derive(Debug)]
pub struct Presets {
    file: Option<PathBuf>,
    state: Mutex<State>,
}

/// Names longer than this are refused (ONVIF's Name is a short string;
/// the web page's button names it).
pub const MAX_NAME: usize = 64;

/// The first character of `name` a preset name may not hold: a control
/// character, or one that changes how the text around it shows without
/// showing itself (Unicode bidirectional controls, which can make a name
/// read as another on an operator's screen, zero-width characters, the
/// byte-order mark). Refused by the doors (issue 49).
pub fn hidden_char(name: &str) -> Option<char> {
    name.chars().find(|&c| {
        c.is_control()
            || matches!(
                c,
                '\u{061C}'
                    | '\u{180E}'
                    | '\u{200B}'..='\u{200F}'
                    | '\u{202A}'..='\u{202E}'
                    | '\u{2060}'..='\u{2069}'
                    | '\u{FEFF}'
            )
    })
}

impl Presets {
    /// Loads `file` when it exists (without a file, names last until exit).
    pub fn load(file: Option<PathBuf>) -> Result<Self, String> {
        let state = match &file {
            Some(path) if path.exists() => {
                let text =
                    std::fs::read_to_string(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
                toml::from_str(&text).map_err(|e| format!("{}: not a preset state file: {e}", path.display()))?
            }
            _ => State::default(),
        };
        Ok(Self {
            file,
            state: Mutex::new(state),
        })
    }

    /// The named presets of `gimbal`, by number.
    pub fn list(&self, gimbal: &str) -> Vec<(u8, String)> {
        let state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let mut list: Vec<(u8, String)> = state
            .gimbal
            .get(gimbal)
            .into_iter()
            .flatten()
            .filter_map(|(n, name)| Some((n.parse().ok()?, name.clone())))
            .collect();
        list.sort();
        list
    }

    /// The lowest number without a name that gcud does not reserve
    /// (`reserved`: the presets its park and tours recall, from `~B`).
    pub fn free(&self, gimbal: &str, reserved: &[u8]) -> Option<u8> {
        let used: Vec<u8> = self.list(gimbal).into_iter().map(|(n, _)| n).collect();
        (0..=255u8).find(|n| !used.contains(n) && !reserved.contains(n))
    }

    /// Names preset `n` (or removes its name) and writes the file.
    pub fn set(&self, gimbal: &str, n: u8, name: Option<&str>) -> Result<(), String> {
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let mut next = state.clone();
        let names = next.gimbal.entry(gimbal.to_owned()).or_default();
        match name {
            Some(name) => names.insert(n.to_string(), name.to_owned()),
            None => names.remove(&n.to_string()),
        };
        if let Some(path) = &self.file {
            let text = toml::to_string(&next).map_err(|e| format!("cannot write the preset names: {e}"))?;
            let tmp = path.with_extension("tmp");
            std::fs::write(&tmp, text)
                .and_then(|()| std::fs::rename(&tmp, path))
                .map_err(|e| format!("{}: cannot write the preset names: {e}", path.display()))?;
        }
        *state = next;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_may_not_hide_characters() {
        assert_eq!(hidden_char("gate 2"), None);
        assert_eq!(hidden_char("Tor Süd"), None);
        assert_eq!(
            hidden_char("gate\u{202E}2etag"),
            Some('\u{202E}'),
            "right-to-left override"
        );
        assert_eq!(hidden_char("ga\u{200B}te"), Some('\u{200B}'), "zero-width space");
        assert_eq!(hidden_char("\u{2066}x"), Some('\u{2066}'), "isolate");
        assert_eq!(hidden_char("a\tb"), Some('\t'));
    }

    #[test]
    fn names_survive_a_reload_and_numbers_are_reused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("presets.toml");
        let p = Presets::load(Some(file.clone())).unwrap();
        assert_eq!(p.free("a", &[]), Some(0));
        assert_eq!(p.free("a", &[0, 1]), Some(2), "park and tour presets are gcud's");
        p.set("a", 0, Some("door")).unwrap();
        p.set("a", 1, Some("gate \"2\"")).unwrap();
        p.set("b", 0, Some("other")).unwrap();
        p.set("a", 0, None).unwrap();
        let again = Presets::load(Some(file)).unwrap();
        assert_eq!(again.list("a"), vec![(1, "gate \"2\"".to_owned())]);
        assert_eq!(again.free("a", &[]), Some(0));
        assert_eq!(again.list("b").len(), 1);
    }
}
