//! Sign-in for the page: a user's name and password (checked in constant
//! time for equal lengths) open a sign-in, kept in memory and named by a
//! random token in the session cookie (HttpOnly, SameSite=Strict, and
//! Secure over HTTPS: `[http] tls`, or `secure_cookie` behind a proxy); its
//! own random CSRF token, which only the page's script can read (from
//! `/api/session`), must come in the `X-CSRF-Token` header of every POST.
//! Sign-ins are bounded: at most `max_sign_ins`, split evenly between the
//! configured users (at least one each), each for `sign_in` from when it
//! opened; a user's new sign-in past its share ends that user's oldest,
//! never another's (issue 49: a viewer's 256 sign-ins ended every other
//! session, the administrator's included).

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Duration;

use base64::Engine;
use tokio::time::Instant;

use crate::config::{Role, User};

/// The session cookie's name.
pub const COOKIE: &str = "sagebrush_web";
/// The header every POST carries its CSRF token in.
pub const CSRF_HEADER: &str = "x-csrf-token";

/// A signed-in user, as the requests see it.
#[derive(Clone, Debug, PartialEq)]
pub struct SignedIn {
    pub user: String,
    pub role: Role,
    pub csrf: String,
}

#[derive(Debug)]
struct Entry {
    who: SignedIn,
    opened: Instant,
}

#[derive(Debug)]
pub struct Auth {
    users: Vec<User>,
    lasts: Duration,
    max: usize,
    open: Mutex<HashMap<String, Entry>>,
}

/// Why a request is not served.
#[derive(Debug, Clone, PartialEq)]
pub enum Refused {
    /// No valid sign-in (401).
    SignIn(&'static str),
    /// Signed in, but not allowed (403): a missing or wrong CSRF token, a role too low.
    Forbidden(String),
}

/// `a == b` without stopping at the first difference.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// 32 random bytes, base64url.
fn token() -> Result<String, String> {
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes).map_err(|e| format!("no random bytes for a token: {e}"))?;
    Ok(base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(bytes))
}

/// The value of cookie `name` in a `Cookie` header.
pub fn cookie<'a>(header: &'a str, name: &str) -> Option<&'a str> {
    header
        .split(';')
        .filter_map(|kv| kv.trim().split_once('='))
        .find(|(k, _)| *k == name)
        .map(|(_, v)| v)
}

impl Auth {
    pub fn new(users: Vec<User>, lasts: Duration, max: usize) -> Self {
        Self {
            users,
            lasts,
            max,
            open: Mutex::new(HashMap::new()),
        }
    }

    /// The index of configured account `user`, if it is one.
    pub fn account(&self, user: &str) -> Option<usize> {
        self.users.iter().position(|u| same(u.name.as_bytes(), user.as_bytes()))
    }

    /// Checks `user` and `password`; on success opens a sign-in and
    /// returns its token (for the cookie) and what it may do.
    pub fn sign_in(&self, user: &str, password: &str, now: Instant) -> Result<(String, SignedIn), String> {
        let found = self
            .users
            .iter()
            .find(|u| same(u.name.as_bytes(), user.as_bytes()))
            .filter(|u| same(u.password.as_bytes(), password.as_bytes()));
        let Some(found) = found else {
            return Err("wrong user or password".to_owned());
        };
        let who = SignedIn {
            user: found.name.clone(),
            role: found.role,
            csrf: token()?,
        };
        let key = token()?;
        let mut open = self.open.lock().unwrap_or_else(|p| p.into_inner());
        open.retain(|_, e| now.duration_since(e.opened) < self.lasts);
        let share = (self.max / self.users.len().max(1)).max(1);
        loop {
            let mine = open.iter().filter(|(_, e)| e.who.user == who.user);
            if mine.clone().count() < share {
                break;
            }
            let oldest = mine.min_by_key(|(_, e)| e.opened).map(|(k, _)| k.clone());
            match oldest {
                Some(k) => open.remove(&k),
                None => break,
            };
        }
        open.insert(
            key.clone(),
            Entry {
                who: who.clone(),
                opened: now,
            },
        );
        Ok((key, who))
    }

    /// Ends the sign-in of `key`.
    pub fn sign_out(&self, key: &str) {
        self.open.lock().unwrap_or_else(|p| p.into_inner()).remove(key);
    }

    /// The sign-in named by the cookie header `cookies`.
    pub fn who(&self, cookies: Option<&str>, now: Instant) -> Result<SignedIn, Refused> {
        let key = cookies
            .and_then(|c| cookie(c, COOKIE))
            .ok_or(Refused::SignIn("not signed in"))?;
        let mut open = self.open.lock().unwrap_or_else(|p| p.into_inner());
        match open.get(key) {
            Some(e) if now.duration_since(e.opened) < self.lasts => Ok(e.who.clone()),
            Some(_) => {
                open.remove(key);
                Err(Refused::SignIn("the sign-in has expired"))
            }
            None => Err(Refused::SignIn("not signed in (or signed out)")),
        }
    }

    /// The sign-in of a state-changing request: its cookie, its CSRF
    /// token in `csrf` (the `X-CSRF-Token` header), and a role of at
    /// least `need` to `what`.
    pub fn allow(
        &self,
        cookies: Option<&str>,
        csrf: Option<&str>,
        need: Role,
        what: &str,
        now: Instant,
    ) -> Result<SignedIn, Refused> {
        let who = self.who(cookies, now)?;
        match csrf {
            Some(t) if same(t.as_bytes(), who.csrf.as_bytes()) => {}
            Some(_) => return Err(Refused::Forbidden("wrong X-CSRF-Token header".to_owned())),
            None => {
                return Err(Refused::Forbidden(
                    "no X-CSRF-Token header: every POST carries the page's token".to_owned(),
                ));
            }
        }
        if who.role < need {
            return Err(Refused::Forbidden(format!(
                "{} ({}) may not {what}: it takes the {} role",
                who.user,
                who.role.name(),
                need.name()
            )));
        }
        Ok(who)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn auth(max: usize) -> Auth {
        let user = |name: &str, role| User {
            name: name.to_owned(),
            password: format!("{name}-pw"),
            role,
        };
        Auth::new(
            vec![user("op", Role::Operator), user("viewer", Role::User)],
            Duration::from_secs(60),
            max,
        )
    }

    #[test]
    fn a_sign_in_needs_the_password_the_csrf_token_and_the_role() {
        let a = auth(8);
        let now = Instant::now();
        assert!(a.sign_in("op", "wrong", now).is_err());
        assert!(a.sign_in("nobody", "op-pw", now).is_err());
        let (key, who) = a.sign_in("op", "op-pw", now).unwrap();
        let header = format!("other=1; {COOKIE}={key}");
        assert_eq!(a.who(Some(&header), now).unwrap(), who);
        let allow = |csrf: Option<&str>, need| a.allow(Some(&header), csrf, need, "move", now);
        assert!(allow(Some(&who.csrf), Role::Operator).is_ok());
        assert!(matches!(allow(None, Role::Operator), Err(Refused::Forbidden(_))));
        assert!(matches!(allow(Some("x"), Role::Operator), Err(Refused::Forbidden(_))));
        assert!(matches!(
            allow(Some(&who.csrf), Role::Administrator),
            Err(Refused::Forbidden(_))
        ));
        assert!(a.who(Some(&header), now + Duration::from_secs(61)).is_err());
        a.sign_out(&key);
        assert!(a.who(Some(&header), now).is_err());
    }

    #[test]
    fn a_users_sign_ins_end_only_that_users_oldest() {
        // 4 sign-ins, 2 users: 2 each.
        let a = auth(4);
        let t = Instant::now();
        let (op, _) = a.sign_in("op", "op-pw", t).unwrap();
        let viewer: Vec<String> = (1..=256)
            .map(|i| {
                a.sign_in("viewer", "viewer-pw", t + Duration::from_millis(i))
                    .unwrap()
                    .0
            })
            .collect();
        let at = t + Duration::from_secs(1);
        let alive = |k: &str| a.who(Some(&format!("{COOKIE}={k}")), at).is_ok();
        assert!(alive(&op), "another user's sign-ins never end the operator's");
        assert_eq!(viewer.iter().filter(|k| alive(k)).count(), 2, "the viewer's share");
        assert!(alive(&viewer[255]) && alive(&viewer[254]), "its newest two");
    }

    #[test]
    fn sign_ins_are_bounded_the_oldest_goes() {
        let a = auth(2);
        let t = Instant::now();
        let (first, _) = a.sign_in("op", "op-pw", t).unwrap();
        let (second, _) = a.sign_in("viewer", "viewer-pw", t + Duration::from_secs(1)).unwrap();
        let (third, _) = a.sign_in("op", "op-pw", t + Duration::from_secs(2)).unwrap();
        let at = t + Duration::from_secs(3);
        assert!(a.who(Some(&format!("{COOKIE}={first}")), at).is_err());
        assert!(a.who(Some(&format!("{COOKIE}={second}")), at).is_ok());
        assert!(a.who(Some(&format!("{COOKIE}={third}")), at).is_ok());
    }
}
