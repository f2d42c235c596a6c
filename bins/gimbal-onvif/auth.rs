//! Who sent a request: WS-Security UsernameToken with PasswordDigest (OASIS
//! UsernameToken Profile 1.0, ONVIF Core 5.12.2): the digest is the base64
//! of SHA-1 over the nonce, Created and the password; Created is within
//! [`WINDOW`] of our clock, and a nonce is never accepted twice. Plain-text
//! passwords are refused.

use std::collections::{HashSet, VecDeque};
use std::sync::Mutex;
use std::time::Duration;

use base64::Engine;
use base64::engine::general_purpose::STANDARD as B64;
use sha1::{Digest, Sha1};
use time::OffsetDateTime;
use time::format_description::well_known::Rfc3339;

use crate::config::{Role, User};
use crate::soap::{Element, Fault};

/// How far Created may be from our clock, either way.
pub const WINDOW: Duration = Duration::from_secs(300);
/// Nonces remembered (each for [`WINDOW`] twice over); beyond this many the
/// oldest is forgotten, and a token that old is refused by its Created.
const NONCES_CAP: usize = 65_536;

#[derive(Debug)]
pub struct Authenticator {
    users: Vec<User>,
    seen: Mutex<Nonces>,
}

/// Nonces accepted: oldest first with when, and as a set.
#[derive(Debug, Default)]
struct Nonces {
    order: VecDeque<(String, OffsetDateTime)>,
    set: HashSet<String>,
}

fn not_authorized(reason: impl Into<String>) -> Fault {
    Fault::sender(&["ter:NotAuthorized"], reason)
}

impl Authenticator {
    pub fn new(users: Vec<User>) -> Self {
        Self {
            users,
            seen: Mutex::new(Nonces::default()),
        }
    }

    /// The role of the request's user, or why it is refused.
    pub fn check(&self, header: Option<&Element>, now: OffsetDateTime) -> Result<(String, Role), Fault> {
        let token = header
            .and_then(|h| h.path(&["Security", "UsernameToken"]))
            .ok_or_else(|| not_authorized("this operation needs a WS-Security UsernameToken (PasswordDigest)"))?;
        let name = token.text_at(&["Username"]).unwrap_or_default();
        let password = token
            .child("Password")
            .ok_or_else(|| not_authorized("the UsernameToken has no Password"))?;
        if !password.attr("Type").is_some_and(|t| t.ends_with("#PasswordDigest")) {
            return Err(not_authorized(
                "only PasswordDigest is accepted, never a plain-text password",
            ));
        }
        let nonce = token.text_at(&["Nonce"]).unwrap_or_default();
        let created = token.text_at(&["Created"]).unwrap_or_default();
        let at = OffsetDateTime::parse(created, &Rfc3339)
            .map_err(|_| not_authorized(format!("Created {created:?} is not an RFC 3339 time")))?;
        let skew = (now - at).unsigned_abs();
        if skew > WINDOW {
            return Err(not_authorized(format!(
                "Created {created} is {} s from this device's clock (at most {} s): set the clock or NTP",
                skew.as_secs(),
                WINDOW.as_secs()
            )));
        }
        let nonce_bytes = B64
            .decode(nonce)
            .map_err(|_| not_authorized("the Nonce is not base64"))?;
        let user = self.users.iter().find(|u| u.name == name);
        let valid = user.is_some_and(|u| {
            let mut h = Sha1::new();
            h.update(&nonce_bytes);
            h.update(created.as_bytes());
            h.update(u.password.as_bytes());
            B64.encode(h.finalize()) == password.text.trim()
        });
        let Some(user) = user.filter(|_| valid) else {
            return Err(not_authorized("wrong user name or password"));
        };
        self.remember(nonce, now)?;
        Ok((user.name.clone(), user.role))
    }

    /// Refuses a nonce already accepted (a replay).
    fn remember(&self, nonce: &str, now: OffsetDateTime) -> Result<(), Fault> {
        let mut guard = self.seen.lock().unwrap_or_else(|p| p.into_inner());
        let Nonces { order, set } = &mut *guard;
        while let Some((old, at)) = order.front() {
            if order.len() >= NONCES_CAP || (now - *at).unsigned_abs() > WINDOW * 2 {
                set.remove(old);
                order.pop_front();
            } else {
                break;
            }
        }
        if set.contains(nonce) {
            return Err(not_authorized("this Nonce was already used (a replayed request)"));
        }
        set.insert(nonce.to_owned());
        order.push_back((nonce.to_owned(), now));
        Ok(())
    }
}

/// Refuses a user whose role is below `needed`.
pub fn require(user: &(String, Role), needed: Role, operation: &str) -> Result<(), Fault> {
    if user.1 >= needed {
        Ok(())
    } else {
        Err(not_authorized(format!(
            "user {:?} ({:?}) may not {operation}: it needs the {:?} role",
            user.0, user.1, needed
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::soap;

    fn header(user: &str, password: &str, nonce: &[u8], created: &str) -> Element {
        let mut h = Sha1::new();
        h.update(nonce);
        h.update(created.as_bytes());
        h.update(password.as_bytes());
        let digest = B64.encode(h.finalize());
        let xml = format!(
            r#"<Header><Security><UsernameToken><Username>{user}</Username><Password Type="http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-username-token-profile-1.0#PasswordDigest">{digest}</Password><Nonce>{}</Nonce><Created>{created}</Created></UsernameToken></Security></Header>"#,
            B64.encode(nonce)
        );
        soap::parse(xml.as_bytes()).unwrap()
    }

    #[test]
    fn digest_window_replay_and_roles() {
        let a = Authenticator::new(vec![User {
            name: "op".into(),
            password: "pw".into(),
            role: Role::Operator,
        }]);
        let now = OffsetDateTime::parse("2026-01-01T00:00:00Z", &Rfc3339).unwrap();
        let ok = header("op", "pw", b"n1", "2026-01-01T00:00:10Z");
        let who = a.check(Some(&ok), now).unwrap();
        assert_eq!(who.1, Role::Operator);
        assert!(a.check(Some(&ok), now).is_err(), "a replayed nonce is refused");
        assert!(
            a.check(Some(&header("op", "no", b"n2", "2026-01-01T00:00:10Z")), now)
                .is_err()
        );
        assert!(
            a.check(Some(&header("op", "pw", b"n3", "2026-01-01T01:00:00Z")), now)
                .is_err()
        );
        assert!(
            a.check(Some(&header("x", "pw", b"n4", "2026-01-01T00:00:00Z")), now)
                .is_err()
        );
        assert!(a.check(None, now).is_err());
        assert!(require(&who, Role::Operator, "move").is_ok());
        assert!(require(&who, Role::Administrator, "reboot").is_err());
    }
}
