//! Who a command comes from (ARCHITECTURE "Principals"): a person or a
//! tool gcud knows (`[[principal]]`), named by its connection's client
//! certificate; a user a door acts for (`~U`); or, on a link without
//! principals, the configured link itself. The governor governs by the
//! [`Actor`]; the audit line and `~C` name it.

use std::sync::Arc;

/// A person or tool gcud knows (gcud's `[[principal]]`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Principal {
    pub name: Arc<str>,
    /// 0..=100: the highest priority its commands hold (capped by its
    /// link's, and by the door's it comes through).
    pub priority: u8,
    /// A door: it may say which of its users each command is for (`~U`).
    pub acts_for_users: bool,
}

/// Who a command is from, to the governor, the audit and `~C`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Actor {
    /// One controller: the principal's name, or the link's on a link
    /// without principals (every connection of one listener is one link).
    pub name: Arc<str>,
    pub priority: u8,
    /// The tool or link its commands came through: the door a user's
    /// command came through, else the link of the principal's connection;
    /// `None` on a link without principals.
    pub via: Option<Arc<str>>,
    /// A user the door named that gcud does not know as a principal: the
    /// command is governed as the door's, and the audit names the user.
    pub for_user: Option<Arc<str>>,
}

impl Actor {
    /// A connection of the link `link` (its name and priority),
    /// authenticated as `principal` when it has one.
    pub fn of_connection(link: &Arc<str>, link_priority: u8, principal: Option<&Principal>) -> Self {
        match principal {
            Some(p) => Actor {
                name: p.name.clone(),
                priority: p.priority.min(link_priority),
                via: Some(link.clone()),
                for_user: None,
            },
            None => Actor {
                name: link.clone(),
                priority: link_priority,
                via: None,
                for_user: None,
            },
        }
    }

    /// This connection's door acting for `user`: a user gcud knows
    /// (`known`) is governed as that principal, its priority capped by the
    /// door's; another is governed as the door.
    pub fn acting_for(&self, user: &Arc<str>, known: Option<&Principal>) -> Self {
        match known {
            Some(p) => Actor {
                name: p.name.clone(),
                priority: p.priority.min(self.priority),
                via: Some(self.name.clone()),
                for_user: None,
            },
            None => Actor {
                for_user: Some(user.clone()),
                ..self.clone()
            },
        }
    }
}

impl std::fmt::Display for Actor {
    /// "alice via gimbal-web", "gimbal-web for bob via doors", "link clients".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.via {
            None => write!(f, "link {}", self.name)?,
            Some(via) => {
                f.write_str(&self.name)?;
                if let Some(user) = &self.for_user {
                    write!(f, " for {user}")?;
                }
                write!(f, " via {via}")?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn principal(name: &str, priority: u8, acts_for_users: bool) -> Principal {
        Principal {
            name: Arc::from(name),
            priority,
            acts_for_users,
        }
    }

    #[test]
    fn a_principal_is_capped_by_its_link_and_a_user_by_the_door() {
        let link: Arc<str> = Arc::from("doors");
        let door = principal("gimbal-web", 70, true);
        let web = Actor::of_connection(&link, 60, Some(&door));
        assert_eq!(web.priority, 60, "capped by the link");
        assert_eq!(web.to_string(), "gimbal-web via doors");
        let alice = principal("alice", 80, false);
        let for_alice = web.acting_for(&Arc::from("alice"), Some(&alice));
        assert_eq!((&*for_alice.name, for_alice.priority), ("alice", 60));
        assert_eq!(for_alice.to_string(), "alice via gimbal-web");
        let bob = web.acting_for(&Arc::from("bob"), None);
        assert_eq!(
            (&*bob.name, bob.priority),
            ("gimbal-web", 60),
            "an unknown user is the door"
        );
        assert_eq!(bob.to_string(), "gimbal-web for bob via doors");
    }

    #[test]
    fn a_link_without_principals_is_its_own_actor() {
        let plain = Actor::of_connection(&Arc::from("clients"), 50, None);
        assert_eq!((&*plain.name, plain.priority, plain.via.clone()), ("clients", 50, None));
        assert_eq!(plain.to_string(), "link clients");
    }
}
