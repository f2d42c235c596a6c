//! `[[route]]` and `gcu.default_route`: where frames for other groups go.

use std::collections::BTreeSet;

use sagebrush_gcu::LinkKind;
use sagebrush_service::config_file::{Int, Source};
use serde::Deserialize;
use toml::Spanned;

use super::{ConfigError, Link};

/// `[[route]]`: a static route, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RouteSection {
    group: Int<u8, 0, 254>,
    link: Spanned<String>,
}

/// The static routes and the default route, validated (a reload replaces
/// them as a whole).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Routes {
    /// `gcu.default_route`: the link frames for unknown groups go to.
    pub default: Option<String>,
    /// `[[route]]`: destination group and link name, in file order.
    pub table: Vec<(u8, String)>,
}

/// A route goes to another GCU: a client is never a destination. A route
/// naming a listener reaches its newest live connection (a GCU that dials
/// in). No route for this GCU's own `group`, none twice.
pub(super) fn validate(
    c: &Source<'_>,
    group: u8,
    default_route: Option<&Spanned<String>>,
    raw: &[RouteSection],
    links: &[Link],
) -> Result<Routes, ConfigError> {
    let routable = |name: &Spanned<String>, key: &str| -> Result<String, ConfigError> {
        match links.iter().find(|l| &l.name == name.get_ref()) {
            None => Err(c.at(name.span(), key, format!("no link is named {:?}", name.get_ref()))),
            Some(l) if l.kind == LinkKind::Client => Err(c.at(
                name.span(),
                key,
                format!(
                    "link {:?} has role \"client\"; routes go to a link to another GCU (role \
                     \"upstream\" or \"downstream\"); answers to clients follow the reverse path",
                    l.name
                ),
            )),
            Some(l) => Ok(l.name.clone()),
        }
    };
    let default = default_route.map(|r| routable(r, "gcu.default_route")).transpose()?;
    let mut table = Vec::new();
    let mut routed = BTreeSet::new();
    for (i, r) in raw.iter().enumerate() {
        let key = format!("route[{i}]");
        let g = r.group.get();
        if g == group {
            return Err(c.at(
                r.group.span(),
                format!("{key}.group"),
                format!("group {g} is this GCU's own group"),
            ));
        }
        if !routed.insert(g) {
            return Err(c.at(
                r.group.span(),
                format!("{key}.group"),
                format!("group {g} has two routes"),
            ));
        }
        table.push((g, routable(&r.link, &format!("{key}.link"))?));
    }
    Ok(Routes { default, table })
}
