//! HTTPS at the doors (issue 49): `[http] tls`, shared by gimbal-web and
//! gimbal-onvif.
//!
//! - `tls = { cert = "FILE.pem", key = "FILE.key" }`: the site's own
//!   certificate (chain first) and key, PEM, read when the configuration is
//!   (an error names the file);
//! - `tls = "self-signed"`: a certificate the door makes once with rcgen
//!   and keeps beside its state file (`state_file`, or systemd's
//!   `$STATE_DIRECTORY`), `DOOR-self-signed.crt` and `DOOR-self-signed.key`
//!   (written 0600), reused at every start while it still names the
//!   listen addresses and localhost (made anew, with a warning, when it
//!   does not, or when it cannot be read). Its subject alternative names:
//!   each listen address (for an unspecified one, the host's name),
//!   `localhost`, 127.0.0.1 and ::1. Every start
//!   logs its SHA-256 fingerprint, which a client that pins it compares.
//!
//! The acceptor is rustls with ring ([`sagebrush_host::tls::acceptor`]);
//! the bounded listener ([`crate::http::serve_http`]) does the handshake
//! inside the connection's admission slot, bounded in time.

use std::fmt::Write as _;
use std::io::Write as _;
use std::net::{IpAddr, SocketAddr};
use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

use sagebrush_host::tls::TlsAcceptor;
use tracing::{info, warn};

use crate::config_file::{ConfigError, Source};
use crate::door_config::HttpSection;

/// What `tls = "self-signed"` is written as.
pub const SELF_SIGNED: &str = "self-signed";
/// How long a self-signed certificate is valid: ten years.
const VALID_DAYS: i64 = 3650;

/// `[http] tls`: where the door's certificate comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DoorTls {
    /// The site's certificate (chain) and key, PEM.
    Files { cert: PathBuf, key: PathBuf },
    /// Made by the door once, kept in `cert` and `key`: it must name
    /// `required`; made, it also names `extra` (the host's name behind
    /// an unspecified listen address).
    SelfSigned {
        cert: PathBuf,
        key: PathBuf,
        required: Vec<String>,
        extra: Vec<String>,
    },
}

impl Source<'_> {
    /// `[http] tls` of door `door` listening on `listens`, its self-signed
    /// certificate kept beside `state_file`; none when absent (plain HTTP).
    pub fn door_tls(
        &self,
        http: &HttpSection,
        door: &str,
        state_file: Option<&Path>,
        listens: &[SocketAddr],
    ) -> Result<Option<DoorTls>, ConfigError> {
        let Some(v) = &http.tls else {
            return Ok(None);
        };
        let key = "http.tls";
        let expected = "expected \"self-signed\" or { cert = \"FILE.pem\", key = \"FILE.key\" }";
        match v.get_ref() {
            toml::Value::String(s) if s == SELF_SIGNED => {
                let Some(state) = state_file else {
                    return Err(self.at(
                        v.span(),
                        key,
                        "\"self-signed\" keeps its certificate beside the state file: set state_file (or run under systemd with a StateDirectory=)",
                    ));
                };
                let folder = match state.parent() {
                    Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                    _ => PathBuf::from("."),
                };
                let (required, extra) = names(listens);
                Ok(Some(DoorTls::SelfSigned {
                    cert: folder.join(format!("{door}-self-signed.crt")),
                    key: folder.join(format!("{door}-self-signed.key")),
                    required,
                    extra,
                }))
            }
            toml::Value::Table(t) => {
                let file = |name: &str| t.get(name).and_then(toml::Value::as_str).map(PathBuf::from);
                let (Some(cert), Some(k), 2) = (file("cert"), file("key"), t.len()) else {
                    return Err(self.at(v.span(), key, expected));
                };
                sagebrush_host::tls::acceptor(&cert, &k, None).map_err(|e| self.at(v.span(), key, e.to_string()))?;
                Ok(Some(DoorTls::Files { cert, key: k }))
            }
            _ => Err(self.at(v.span(), key, expected)),
        }
    }
}

/// `--check`'s warnings: each of `listeners` off loopback served in plain
/// HTTP (`tls` false).
pub fn plain_http_warnings(listeners: &[SocketAddr], tls: bool) -> Vec<String> {
    if tls {
        return Vec::new();
    }
    listeners
        .iter()
        .filter(|l| !l.ip().is_loopback())
        .map(|l| {
            format!("{l} serves the network in plain HTTP: what crosses it (sign-ins, commands) can be read and changed on the way; set [http] tls")
        })
        .collect()
}

/// The names a self-signed certificate must hold for `listens` (each
/// specified address, `localhost`, 127.0.0.1, ::1), and those it also
/// gets when made (for an unspecified address: the host's name; name a
/// listen address to have it named).
fn names(listens: &[SocketAddr]) -> (Vec<String>, Vec<String>) {
    let mut required: Vec<String> = vec!["localhost".into(), "127.0.0.1".into(), "::1".into()];
    let mut extra = Vec::new();
    let add = |list: &mut Vec<String>, name: String| {
        if !list.contains(&name) {
            list.push(name);
        }
    };
    for l in listens {
        if !l.ip().is_unspecified() {
            add(&mut required, l.ip().to_canonical().to_string());
            continue;
        }
        if let Ok(host) = nix::unistd::gethostname() {
            if let Some(host) = host.to_str().filter(|h| !h.is_empty()) {
                add(&mut extra, host.to_owned());
            }
        }
    }
    extra.retain(|n| !required.contains(n));
    (required, extra)
}

impl DoorTls {
    /// The acceptor: the site's files, or the self-signed certificate
    /// (made now when there is none that names the listen addresses).
    pub fn acceptor(&self) -> Result<TlsAcceptor, String> {
        let (cert, key) = match self {
            DoorTls::Files { cert, key } => (cert, key),
            DoorTls::SelfSigned {
                cert,
                key,
                required,
                extra,
            } => {
                keep_self_signed(cert, key, required, extra)?;
                (cert, key)
            }
        };
        let acceptor = sagebrush_host::tls::acceptor(cert, key, None).map_err(|e| format!("[http] tls: {e}"))?;
        let pem = std::fs::read(cert).map_err(|e| format!("{}: {e}", cert.display()))?;
        info!(cert = %cert.display(), sha256 = %fingerprint(&pem).unwrap_or_default(), "HTTPS: the certificate served");
        Ok(acceptor)
    }
}

/// The SHA-256 fingerprint of the first certificate of `pem`, as
/// browsers and `openssl x509 -fingerprint -sha256` show it.
pub fn fingerprint(pem: &[u8]) -> Option<String> {
    let (_, block) = x509_parser::pem::parse_x509_pem(pem).ok()?;
    let digest = ring::digest::digest(&ring::digest::SHA256, &block.contents);
    let mut out = String::new();
    for (i, b) in digest.as_ref().iter().enumerate() {
        let _ = write!(out, "{}{b:02X}", if i == 0 { "" } else { ":" });
    }
    Some(out)
}

/// The names (DNS names and IP addresses, as text) of the certificate in `pem`.
fn certificate_names(pem: &[u8]) -> Option<Vec<String>> {
    let (_, block) = x509_parser::pem::parse_x509_pem(pem).ok()?;
    let cert = block.parse_x509().ok()?;
    let san = cert.subject_alternative_name().ok()??;
    let names = san
        .value
        .general_names
        .iter()
        .filter_map(|n| match n {
            x509_parser::extensions::GeneralName::DNSName(d) => Some((*d).to_owned()),
            x509_parser::extensions::GeneralName::IPAddress(b) => match b.len() {
                4 => <[u8; 4]>::try_from(*b).ok().map(|a| IpAddr::from(a).to_string()),
                16 => <[u8; 16]>::try_from(*b).ok().map(|a| IpAddr::from(a).to_string()),
                _ => None,
            },
            _ => None,
        })
        .collect();
    Some(names)
}

/// Keeps a self-signed certificate in `cert` and `key`: the one there
/// when it names `required` and its key reads, else a new one naming
/// `required` and `extra`.
fn keep_self_signed(cert: &Path, key: &Path, required: &[String], extra: &[String]) -> Result<(), String> {
    let why = match (std::fs::read(cert), std::fs::read(key)) {
        (Ok(pem), Ok(_)) => match certificate_names(&pem) {
            Some(held) => match required.iter().find(|n| !held.contains(n)) {
                None => {
                    if let Ok(meta) = std::fs::metadata(key) {
                        if meta.permissions().mode() & 0o077 != 0 {
                            warn!(key = %key.display(), "the self-signed certificate's key is readable by others: chmod 600 it");
                        }
                    }
                    return Ok(());
                }
                Some(missing) => format!("it does not name {missing}"),
            },
            None => "it cannot be read".to_owned(),
        },
        (Err(e), _) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
        (Err(e), _) => format!("{}: {e}", cert.display()),
        (_, Err(e)) => format!("{}: {e}", key.display()),
    };
    if !why.is_empty() {
        warn!(cert = %cert.display(), "the kept self-signed certificate is made anew: {why}");
    }
    let (cert_pem, key_pem) = make_self_signed(required, extra)?;
    write_file(key, &key_pem, 0o600)?;
    write_file(cert, &cert_pem, 0o644)?;
    info!(cert = %cert.display(), key = %key.display(), names = [required, extra].concat().join(", "), "HTTPS: a self-signed certificate made and kept");
    Ok(())
}

/// A self-signed certificate for `required` and `extra` and its key, PEM.
fn make_self_signed(required: &[String], extra: &[String]) -> Result<(String, String), String> {
    let names: Vec<String> = required.iter().chain(extra).cloned().collect();
    let mut params =
        rcgen::CertificateParams::new(names).map_err(|e| format!("a self-signed certificate's names: {e}"))?;
    let mut dn = rcgen::DistinguishedName::new();
    dn.push(rcgen::DnType::CommonName, "Sagebrush gimbal door (self-signed)");
    params.distinguished_name = dn;
    let now = time::OffsetDateTime::now_utc();
    params.not_before = now - time::Duration::days(1);
    params.not_after = now + time::Duration::days(VALID_DAYS);
    params.extended_key_usages = vec![rcgen::ExtendedKeyUsagePurpose::ServerAuth];
    let key = rcgen::KeyPair::generate().map_err(|e| format!("a key for the self-signed certificate: {e}"))?;
    let cert = params
        .self_signed(&key)
        .map_err(|e| format!("the self-signed certificate: {e}"))?;
    Ok((cert.pem(), key.serialize_pem()))
}

/// Writes `text` to `path` with `mode`, through a temporary file renamed
/// over it (never half written).
fn write_file(path: &Path, text: &str, mode: u32) -> Result<(), String> {
    let tmp = path.with_extension("tmp");
    let failed = |e: std::io::Error| format!("cannot write {}: {e}", path.display());
    let _ = std::fs::remove_file(&tmp);
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(mode)
        .open(&tmp)
        .map_err(failed)?;
    f.write_all(text.as_bytes())
        .and_then(|()| f.sync_all())
        .map_err(failed)?;
    std::fs::rename(&tmp, path).map_err(failed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(tls: &str, state: Option<&Path>) -> Result<Option<DoorTls>, ConfigError> {
        let text = format!("[http]\ntls = {tls}\n");
        #[derive(serde::Deserialize)]
        struct File {
            http: HttpSection,
        }
        let f: File = toml::from_str(&text).unwrap();
        let listens = ["127.0.0.1:8443".parse().unwrap(), "10.1.2.3:8443".parse().unwrap()];
        Source::new(Path::new("d.toml"), &text).door_tls(&f.http, "gimbal-web", state, &listens)
    }

    #[test]
    fn a_self_signed_certificate_is_made_once_0600_and_names_the_listen_addresses() {
        let dir = tempfile::tempdir().unwrap();
        let state = dir.path().join("presets.toml");
        let tls = parse("\"self-signed\"", Some(&state)).unwrap().unwrap();
        let DoorTls::SelfSigned {
            cert, key, required, ..
        } = &tls
        else {
            panic!("{tls:?}")
        };
        assert_eq!(cert, &dir.path().join("gimbal-web-self-signed.crt"));
        for n in ["localhost", "127.0.0.1", "::1", "10.1.2.3"] {
            assert!(required.contains(&n.to_owned()), "{required:?}");
        }
        tls.acceptor().unwrap();
        assert_eq!(std::fs::metadata(key).unwrap().permissions().mode() & 0o777, 0o600);
        let first = std::fs::read(cert).unwrap();
        let held = certificate_names(&first).unwrap();
        assert!(required.iter().all(|n| held.contains(n)), "{held:?}");
        // Kept: a second start serves the same certificate.
        tls.acceptor().unwrap();
        assert_eq!(std::fs::read(cert).unwrap(), first);
        assert_eq!(fingerprint(&first).unwrap().len(), 32 * 3 - 1);
        // One that no longer names a listen address is made anew.
        let DoorTls::SelfSigned { cert, key, extra, .. } = tls.clone() else {
            unreachable!()
        };
        let moved = DoorTls::SelfSigned {
            cert: cert.clone(),
            key,
            required: vec!["10.9.9.9".into()],
            extra,
        };
        moved.acceptor().unwrap();
        assert_ne!(std::fs::read(&cert).unwrap(), first);
    }

    #[test]
    fn tls_is_self_signed_or_files_and_an_error_names_its_place() {
        assert!(
            parse("\"self-signed\"", None)
                .unwrap_err()
                .to_string()
                .contains("set state_file")
        );
        let e = parse("\"yes\"", None).unwrap_err().to_string();
        assert!(
            e.starts_with("d.toml:2:7: http.tls: expected \"self-signed\" or"),
            "{e}"
        );
        let e = parse("{ cert = \"/nonexistent/a.pem\", key = \"/nonexistent/a.key\" }", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/a.pem"), "{e}");
        assert!(parse("{ cert = \"a.pem\" }", None).is_err());
    }

    #[test]
    fn plain_http_off_loopback_is_warned_of() {
        let lan: SocketAddr = "0.0.0.0:8080".parse().unwrap();
        let lo: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        assert_eq!(plain_http_warnings(&[lo, lan], false).len(), 1);
        assert!(plain_http_warnings(&[lo], false).is_empty());
        assert!(plain_http_warnings(&[lan], true).is_empty());
    }

    /// gimbal-web's case: HTTPS served through the bounded listener, a
    /// table of one connection. A client that connects and never shakes
    /// hands holds the slot for the handshake time-out, then is closed;
    /// plain HTTP is answered 400; a TLS client trusting the self-signed
    /// certificate gets its answer.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_half_open_client_holds_its_slot_for_the_handshake_time_out_only() {
        use std::io::{Read, Write};
        use std::time::{Duration, Instant};
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let dir = tempfile::tempdir().unwrap();
        let tls = parse("\"self-signed\"", Some(&dir.path().join("presets.toml")))
            .unwrap()
            .unwrap();
        let acceptor = tls.acceptor().unwrap();
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let table = crate::Connections::new(crate::Limits {
            max_total: 1,
            max_per_peer: 1,
            cap_loopback: true,
            idle_timeout: Duration::from_secs(60),
        });
        let limits = crate::HttpLimits {
            handshake_timeout: Duration::from_millis(400),
            ..crate::HttpLimits::default()
        };
        let service = tower::service_fn(|_: hyper::Request<crate::http::RequestBody>| async {
            Ok::<_, std::convert::Infallible>(hyper::Response::new("hello over tls".to_owned()))
        });
        tokio::spawn(crate::serve_http(
            crate::BoundedListener::new(listener, table, "test"),
            limits,
            Some(acceptor),
            service,
        ));
        tokio::task::spawn_blocking(move || {
            // Silent: closed after the handshake time-out, not before.
            let mut silent = std::net::TcpStream::connect(addr).unwrap();
            silent.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            let started = Instant::now();
            // Meanwhile it counts: the one slot is its, a newcomer is closed at once.
            std::thread::sleep(Duration::from_millis(100));
            let mut refused = std::net::TcpStream::connect(addr).unwrap();
            refused.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            let _ = refused.write_all(b"\x16");
            assert!(matches!(refused.read(&mut [0u8; 1]), Ok(0) | Err(_)));
            assert!(started.elapsed() < Duration::from_millis(350), "refused at once");
            let _ = silent.read_to_end(&mut Vec::new());
            let waited = started.elapsed();
            assert!(
                waited >= Duration::from_millis(350) && waited < Duration::from_secs(3),
                "{waited:?}"
            );
            // Plain HTTP: a 400 that says https.
            let mut plain = std::net::TcpStream::connect(addr).unwrap();
            plain.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
            plain.write_all(b"GET / HTTP/1.1\r\nhost: x\r\n\r\n").unwrap();
            let mut answer = String::new();
            let _ = plain.read_to_string(&mut answer);
            assert!(
                answer.starts_with("HTTP/1.1 400") && answer.contains("https://"),
                "{answer:?}"
            );
        })
        .await
        .unwrap();
        // TLS, the self-signed certificate as the client's trust anchor.
        let DoorTls::SelfSigned { cert, .. } = &tls else {
            unreachable!()
        };
        let connector = sagebrush_host::tls::connector(cert, None).unwrap();
        let tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
        let mut s = sagebrush_host::tls::connect(&connector, &addr.to_string(), tcp)
            .await
            .unwrap();
        s.write_all(b"GET / HTTP/1.1\r\nhost: x\r\nconnection: close\r\n\r\n")
            .await
            .unwrap();
        let mut answer = String::new();
        let _ = s.read_to_string(&mut answer).await;
        assert!(
            answer.starts_with("HTTP/1.1 200") && answer.ends_with("hello over tls"),
            "{answer:?}"
        );
    }
}
