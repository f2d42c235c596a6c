//! Who sent a request (ONVIF Core 5.12): WS-Security UsernameToken with
//! PasswordDigest (OASIS UsernameToken Profile 1.0: the digest is the base64
//! of SHA-1 over the nonce, Created and the password; Created is within
//! [`WINDOW`] of our clock, and a nonce is never accepted twice), or HTTP
//! Digest (RFC 7616, MD5, qop=auth: our nonces carry their time and a keyed
//! hash, live [`WINDOW`], and each nonce count is accepted once, for the
//! request URI it was computed over). Plain-text passwords are refused.
//!
//! Bounds (`[auth]`): every nonce accepted is remembered as long as a token
//! carrying it could be accepted (twice [`WINDOW`]); when `nonce_cache` of
//! them are remembered, new requests are refused with a fault until old
//! ones expire (a flood never makes the door forget one early). Each user
//! has a token bucket (`requests_per_s`, `burst`): past it, requests are
//! refused with a fault before anything is remembered or sent to a gimbal.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::Mutex;
use std::time::Duration;

use sagebrush_service::rate::TokenBucket;

use base64::Engine;
use base64::engine::general_purpose::STANDARD as B64;
use sha1::{Digest, Sha1};
use time::OffsetDateTime;
use time::format_description::well_known::Rfc3339;

use crate::config::{AuthBounds, Role, User, Users};
use crate::soap::{Element, Fault};

/// How far Created may be from our clock, either way.
pub const WINDOW: Duration = Duration::from_secs(300);
/// The only WS-Security password type accepted (UsernameToken Profile 1.0, 4.1).
pub const PASSWORD_DIGEST: &str =
    "http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-username-token-profile-1.0#PasswordDigest";

#[derive(Debug)]
pub struct Authenticator {
    users: Vec<User>,
    bounds: AuthBounds,
    seen: Mutex<Nonces>,
    /// Per user name: its request bucket.
    rates: Mutex<HashMap<String, TokenBucket>>,
    /// The key of our HTTP Digest nonces, new at every start.
    secret: [u8; 16],
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

/// Credentials came and were wrong for user `name` (logged as a failed login).
fn login_failed(name: &str, reason: impl Into<String>) -> Fault {
    Fault {
        login_failed: Some(name.to_owned()),
        ..unauthenticated(reason)
    }
}

/// No valid credentials: a 401 with a Digest challenge.
fn unauthenticated(reason: impl Into<String>) -> Fault {
    Fault {
        unauthenticated: true,
        ..not_authorized(reason)
    }
}

/// The realm of HTTP Digest challenges.
pub const REALM: &str = "gimbal-onvif";

fn md5_hex(text: &str) -> String {
    md5::Md5::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The `key=value` and `key="value"` pairs of an Authorization header.
fn digest_fields(header: &str) -> Option<Vec<(String, String)>> {
    let mut rest = header.trim().strip_prefix("Digest")?.trim_start();
    let mut fields = Vec::new();
    while !rest.is_empty() {
        let (key, after) = rest.split_once('=')?;
        let after = after.trim_start();
        let (value, next) = match after.strip_prefix('"') {
            Some(quoted) => {
                let end = quoted.find('"')?;
                (&quoted[..end], &quoted[end + 1..])
            }
            None => after.split_once(',').map_or((after, ""), |(v, n)| (v, n)),
        };
        fields.push((key.trim().to_ascii_lowercase(), value.trim().to_owned()));
        rest = next.trim_start().trim_start_matches(',').trim_start();
        if fields.len() > 16 {
            return None;
        }
    }
    Some(fields)
}

impl Authenticator {
    pub fn new(users: Users) -> Self {
        let mut secret = [0u8; 16];
        if getrandom::fill(&mut secret).is_err() {
            // No system randomness: a key from the clock and the process,
            // still unknown to a client that never saw this start.
            let seed = format!("{:?} {}", std::time::SystemTime::now(), std::process::id());
            secret.copy_from_slice(&Sha1::digest(seed.as_bytes())[..16]);
        }
        Self {
            users: users.list,
            bounds: users.bounds,
            seen: Mutex::new(Nonces::default()),
            rates: Mutex::new(HashMap::new()),
            secret,
        }
    }

    fn nonce_mac(&self, stamp: &str) -> String {
        let mut h = Sha1::new();
        h.update(self.secret);
        h.update(stamp.as_bytes());
        h.finalize()[..12].iter().map(|b| format!("{b:02x}")).collect()
    }

    /// The `WWW-Authenticate` value of a 401: a fresh nonce, valid for [`WINDOW`].
    pub fn challenge(&self, now: OffsetDateTime) -> String {
        let stamp = format!("{:x}", now.unix_timestamp());
        format!(
            "Digest realm=\"{REALM}\", qop=\"auth\", algorithm=MD5, nonce=\"{stamp}.{}\"",
            self.nonce_mac(&stamp)
        )
    }

    /// The user of a request: from its WS-Security header when it has one,
    /// else from its HTTP Digest `authorization` of `method uri` (the
    /// request's own target).
    pub fn authenticate(
        &self,
        header: Option<&Element>,
        authorization: Option<&str>,
        method: &str,
        uri: &str,
        now: OffsetDateTime,
    ) -> Result<(String, Role), Fault> {
        let has_token = header.and_then(|h| h.path(&["Security", "UsernameToken"])).is_some();
        match authorization {
            Some(a) if !has_token && a.trim_start().starts_with("Digest") => {
                self.check_http_digest(a, method, uri, now)
            }
            _ => self.check(header, now),
        }
    }

    /// Takes one request from `user`'s bucket, or refuses it.
    fn spend(&self, user: &str) -> Result<(), Fault> {
        let mut rates = self.rates.lock().unwrap_or_else(|p| p.into_inner());
        let now = tokio::time::Instant::now();
        let AuthBounds {
            requests_per_s, burst, ..
        } = self.bounds;
        let bucket = rates
            .entry(user.to_owned())
            .or_insert_with(|| TokenBucket::new(f64::from(requests_per_s), f64::from(burst), now));
        if bucket.take(now) {
            Ok(())
        } else {
            Err(Fault::sender(
                &["ter:TooManyRequests"],
                format!(
                    "user {user:?} sent more than {requests_per_s} requests a second (burst {burst}): [auth] requests_per_s"
                ),
            ))
        }
    }

    /// HTTP Digest (RFC 7616, MD5, qop=auth) with one of our nonces, over
    /// `method` and the request's target `request_uri`.
    pub fn check_http_digest(
        &self,
        authorization: &str,
        method: &str,
        request_uri: &str,
        now: OffsetDateTime,
    ) -> Result<(String, Role), Fault> {
        let fields = digest_fields(authorization).ok_or_else(|| unauthenticated("malformed Digest authorization"))?;
        let field = |k: &str| {
            fields
                .iter()
                .find(|(key, _)| key == k)
                .map(|(_, v)| v.as_str())
                .unwrap_or_default()
        };
        let (name, nonce, uri, nc, cnonce, response) = (
            field("username"),
            field("nonce"),
            field("uri"),
            field("nc"),
            field("cnonce"),
            field("response"),
        );
        if field("realm") != REALM || field("qop") != "auth" || nc.is_empty() || cnonce.is_empty() {
            return Err(unauthenticated(format!(
                "Digest authorization: expected realm {REALM:?} and qop=auth"
            )));
        }
        if !matches!(field("algorithm"), "" | "MD5") {
            return Err(unauthenticated("Digest authorization: only algorithm MD5 is offered"));
        }
        if uri != request_uri {
            return Err(login_failed(
                name,
                "Digest authorization: its uri is not this request's target",
            ));
        }
        let (stamp, mac) = nonce.split_once('.').unwrap_or_default();
        let issued = i64::from_str_radix(stamp, 16)
            .ok()
            .and_then(|t| OffsetDateTime::from_unix_timestamp(t).ok());
        let fresh = issued.is_some_and(|t| (now - t).unsigned_abs() <= WINDOW);
        if mac != self.nonce_mac(stamp) || !fresh {
            return Err(unauthenticated(
                "stale or foreign Digest nonce: answer the new challenge",
            ));
        }
        let user = self.users.iter().find(|u| u.name == name);
        let valid = user.is_some_and(|u| {
            let ha1 = md5_hex(&format!("{name}:{REALM}:{}", u.password));
            let ha2 = md5_hex(&format!("{method}:{uri}"));
            md5_hex(&format!("{ha1}:{nonce}:{nc}:{cnonce}:auth:{ha2}")) == response
        });
        let Some(user) = user.filter(|_| valid) else {
            return Err(login_failed(name, "wrong user name or password"));
        };
        self.spend(&user.name)?;
        self.remember(&format!("{nonce}:{nc}:{cnonce}"), now)?;
        Ok((user.name.clone(), user.role))
    }

    /// The role of the request's user, or why it is refused.
    pub fn check(&self, header: Option<&Element>, now: OffsetDateTime) -> Result<(String, Role), Fault> {
        let token = header
            .and_then(|h| h.path(&["Security", "UsernameToken"]))
            .ok_or_else(|| {
                unauthenticated("this operation needs a WS-Security UsernameToken (PasswordDigest) or HTTP Digest")
            })?;
        let name = token.text_at(&["Username"]).unwrap_or_default();
        let password = token
            .child("Password")
            .ok_or_else(|| not_authorized("the UsernameToken has no Password"))?;
        if password.attr("Type") != Some(PASSWORD_DIGEST) {
            return Err(not_authorized(format!(
                "only the Password Type {PASSWORD_DIGEST} is accepted, never a plain-text password"
            )));
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
            return Err(login_failed(name, "wrong user name or password"));
        };
        self.spend(&user.name)?;
        self.remember(nonce, now)?;
        Ok((user.name.clone(), user.role))
    }

    /// Refuses a nonce already accepted (a replay). A nonce is remembered
    /// for twice [`WINDOW`] (a token is accepted while its Created is
    /// within [`WINDOW`] of our clock either way); when `nonce_cache` are
    /// remembered, the request is refused rather than one forgotten early.
    fn remember(&self, nonce: &str, now: OffsetDateTime) -> Result<(), Fault> {
        let mut guard = self.seen.lock().unwrap_or_else(|p| p.into_inner());
        let Nonces { order, set } = &mut *guard;
        while let Some((old, at)) = order.front() {
            if (now - *at).unsigned_abs() > WINDOW * 2 {
                set.remove(old);
                order.pop_front();
            } else {
                break;
            }
        }
        if set.contains(nonce) {
            return Err(not_authorized("this Nonce was already used (a replayed request)"));
        }
        if order.len() >= self.bounds.nonce_cache {
            return Err(Fault::sender(
                &["ter:TooManyRequests"],
                format!(
                    "{} nonces of the last {} s are remembered, the most [auth] nonce_cache allows: retry later",
                    order.len(),
                    (WINDOW * 2).as_secs()
                ),
            ));
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
            "user {:?} ({}) may not {operation}: it needs the {} role",
            user.0,
            user.1.name(),
            needed.name()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::soap;

    fn users(requests_per_s: u32, burst: u32, nonce_cache: usize) -> Users {
        Users {
            list: vec![User {
                name: "op".into(),
                password: "pw".into(),
                role: Role::Operator,
            }],
            bounds: AuthBounds {
                requests_per_s,
                burst,
                nonce_cache,
            },
        }
    }

    fn header(user: &str, password: &str, nonce: &[u8], created: &str) -> Element {
        header_typed(user, password, nonce, created, PASSWORD_DIGEST)
    }

    fn header_typed(user: &str, password: &str, nonce: &[u8], created: &str, kind: &str) -> Element {
        let mut h = Sha1::new();
        h.update(nonce);
        h.update(created.as_bytes());
        h.update(password.as_bytes());
        let digest = B64.encode(h.finalize());
        let xml = format!(
            r#"<Header><Security><UsernameToken><Username>{user}</Username><Password Type="{kind}">{digest}</Password><Nonce>{}</Nonce><Created>{created}</Created></UsernameToken></Security></Header>"#,
            B64.encode(nonce)
        );
        soap::parse(xml.as_bytes()).unwrap()
    }

    /// The nonce of a fresh HTTP Digest challenge.
    fn issued_nonce(a: &Authenticator, now: OffsetDateTime) -> String {
        let challenge = a.challenge(now);
        let nonce = challenge.split("nonce=\"").nth(1).expect("a nonce");
        nonce.trim_end_matches('"').to_owned()
    }

    /// An HTTP Digest answer (RFC 7616, qop=auth, MD5) of `user` to
    /// `nonce` for POST `uri`.
    fn digest_answer(user: &str, password: &str, nonce: &str, nc: &str, uri: &str) -> String {
        let ha1 = md5_hex(&format!("{user}:{REALM}:{password}"));
        let ha2 = md5_hex(&format!("POST:{uri}"));
        let response = md5_hex(&format!("{ha1}:{nonce}:{nc}:abc:auth:{ha2}"));
        format!(
            r#"Digest username="{user}", realm="{REALM}", nonce="{nonce}", uri="{uri}", qop=auth, nc={nc}, cnonce="abc", response="{response}", algorithm=MD5"#
        )
    }

    #[test]
    fn http_digest_challenge_answer_replay_and_staleness() {
        let a = Authenticator::new(users(1000, 1000, 1000));
        let now = OffsetDateTime::parse("2026-01-01T00:00:00Z", &Rfc3339).unwrap();
        let nonce = issued_nonce(&a, now);
        let answer = |password: &str, nc: &str| digest_answer("op", password, &nonce, nc, "/onvif/ptz_service");
        assert_eq!(
            a.check_http_digest(&answer("pw", "00000001"), "POST", "/onvif/ptz_service", now)
                .unwrap()
                .1,
            Role::Operator
        );
        assert!(
            a.check_http_digest(&answer("pw", "00000001"), "POST", "/onvif/ptz_service", now)
                .is_err(),
            "replayed nc"
        );
        assert!(
            a.check_http_digest(&answer("pw", "00000002"), "POST", "/onvif/ptz_service", now)
                .is_ok()
        );
        let wrong = a
            .check_http_digest(&answer("no", "00000003"), "POST", "/onvif/ptz_service", now)
            .unwrap_err();
        assert_eq!(wrong.status(soap::Version::Soap12), 401);
        let later = now + Duration::from_secs(600);
        assert!(
            a.check_http_digest(&answer("pw", "00000004"), "POST", "/onvif/ptz_service", later)
                .is_err(),
            "stale nonce"
        );
        let forged = answer("pw", "00000005").replace(&nonce[..4], "0000");
        assert!(
            a.check_http_digest(&forged, "POST", "/onvif/ptz_service", now).is_err(),
            "a nonce we did not issue"
        );
        assert!(
            a.check_http_digest("Digest garbage", "POST", "/onvif/ptz_service", now)
                .is_err()
        );
        assert!(
            a.check_http_digest("Digest a=\"", "POST", "/onvif/ptz_service", now)
                .is_err()
        );
    }

    #[test]
    fn digest_window_replay_and_roles() {
        let a = Authenticator::new(users(1000, 1000, 1000));
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

    #[test]
    fn the_password_type_is_matched_exactly() {
        let a = Authenticator::new(users(1000, 1000, 1000));
        let now = OffsetDateTime::parse("2026-01-01T00:00:00Z", &Rfc3339).unwrap();
        let created = "2026-01-01T00:00:10Z";
        let forged = format!("urn:anything{}", &PASSWORD_DIGEST[PASSWORD_DIGEST.find('#').unwrap()..]);
        assert!(
            a.check(Some(&header_typed("op", "pw", b"t1", created, &forged)), now)
                .is_err()
        );
        assert!(a.check(Some(&header("op", "pw", b"t2", created)), now).is_ok());
    }

    #[test]
    fn a_digest_for_another_uri_is_refused() {
        let a = Authenticator::new(users(1000, 1000, 1000));
        let now = OffsetDateTime::parse("2026-01-01T00:00:00Z", &Rfc3339).unwrap();
        let nonce = issued_nonce(&a, now);
        let header = digest_answer("op", "pw", &nonce, "00000001", "/onvif/device_service");
        let refused = a
            .check_http_digest(&header, "POST", "/onvif/ptz_service", now)
            .unwrap_err();
        assert_eq!(refused.login_failed.as_deref(), Some("op"));
        assert!(
            a.check_http_digest(&header, "POST", "/onvif/device_service", now)
                .is_ok()
        );
    }

    #[test]
    fn a_full_nonce_cache_refuses_newcomers_and_forgets_nothing_early() {
        let a = Authenticator::new(users(1000, 1000, 16));
        let now = OffsetDateTime::parse("2026-01-01T00:00:00Z", &Rfc3339).unwrap();
        let created = "2026-01-01T00:00:10Z";
        let first = header("op", "pw", b"first", created);
        assert!(a.check(Some(&first), now).is_ok());
        for i in 0..15u32 {
            assert!(
                a.check(Some(&header("op", "pw", &i.to_be_bytes(), created)), now)
                    .is_ok()
            );
        }
        let full = a
            .check(Some(&header("op", "pw", b"one more", created)), now)
            .unwrap_err();
        assert_eq!(full.subcodes, ["ter:TooManyRequests"]);
        assert!(
            a.check(Some(&first), now).is_err(),
            "the first nonce is still remembered"
        );
        let later = now + WINDOW * 2 + Duration::from_secs(1);
        let fresh = header("op", "pw", b"fresh", "2026-01-01T00:10:01Z");
        assert!(a.check(Some(&fresh), later).is_ok(), "expired nonces made room");
    }

    #[test]
    fn a_user_past_its_rate_is_refused_before_its_nonce_is_remembered() {
        let a = Authenticator::new(users(1, 3, 1000));
        let now = OffsetDateTime::parse("2026-01-01T00:00:00Z", &Rfc3339).unwrap();
        let created = "2026-01-01T00:00:10Z";
        let refused = (0..10u32)
            .filter(|i| {
                a.check(Some(&header("op", "pw", &i.to_be_bytes(), created)), now)
                    .is_err()
            })
            .count();
        assert!(
            refused >= 6,
            "at most the burst and what refilled meanwhile: {refused} refused"
        );
        assert_eq!(a.seen.lock().unwrap().order.len(), 10 - refused);
    }
}
