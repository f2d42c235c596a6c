//! The door's topics (README "MQTT"), fixed so that deployment tools and
//! tests can rely on them: `<prefix>/<site>/status`, and per gimbal
//! `<prefix>/<site>/<gimbal>/state`, `.../cmd` and `.../result`.

use crate::config::Config;

#[derive(Clone, Debug)]
pub struct Topics {
    /// `<prefix>/<site>`.
    site: String,
    /// `<discovery_prefix>/status`, Home Assistant's birth and will.
    pub home_assistant: Option<String>,
}

impl Topics {
    pub fn new(config: &Config) -> Self {
        Self {
            site: format!("{}/{}", config.prefix, config.site),
            home_assistant: config.discovery_prefix.as_ref().map(|p| format!("{p}/status")),
        }
    }

    /// `online` / `offline`, retained; the last will.
    pub fn status(&self) -> String {
        format!("{}/status", self.site)
    }

    pub fn state(&self, gimbal: &str) -> String {
        format!("{}/{gimbal}/state", self.site)
    }

    pub fn cmd(&self, gimbal: &str) -> String {
        format!("{}/{gimbal}/cmd", self.site)
    }

    pub fn result(&self, gimbal: &str) -> String {
        format!("{}/{gimbal}/result", self.site)
    }

    /// The one subscription of every gimbal's commands.
    pub fn cmd_filter(&self) -> String {
        format!("{}/+/cmd", self.site)
    }

    /// The gimbal a topic of [`Topics::cmd_filter`] names.
    pub fn gimbal_of_cmd<'t>(&self, topic: &'t str) -> Option<&'t str> {
        topic
            .strip_prefix(self.site.as_str())?
            .strip_prefix('/')?
            .strip_suffix("/cmd")
            .filter(|g| !g.contains('/'))
    }
}
