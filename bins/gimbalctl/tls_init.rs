//! `gimbalctl tls init`: a private CA, gcud's certificate and one client
//! certificate per principal (ARCHITECTURE "Principals"), written with
//! rcgen so that a site switches TLS on in minutes. Nothing is
//! overwritten; keys are written 0600.

use std::io::Write;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use rcgen::{
    BasicConstraints, Certificate, CertificateParams, DistinguishedName, DnType, ExtendedKeyUsagePurpose, IsCa,
    KeyPair, KeyUsagePurpose,
};

use crate::error::CtlError;

/// How long the certificates are valid: ten years (a private CA's site
/// replaces them by running this again into a new directory).
const VALID_DAYS: i64 = 3650;

fn params(cn: &str) -> CertificateParams {
    let mut p = CertificateParams::default();
    let mut dn = DistinguishedName::new();
    dn.push(DnType::CommonName, cn);
    p.distinguished_name = dn;
    let now = time::OffsetDateTime::now_utc();
    p.not_before = now - time::Duration::days(1);
    p.not_after = now + time::Duration::days(VALID_DAYS);
    p
}

fn failed(what: &str) -> impl Fn(rcgen::Error) -> CtlError + '_ {
    move |e| CtlError::Io(format!("cannot make {what}: {e}"))
}

/// One certificate signed by the CA: gcud's (a server, for `hosts`) or a principal's (a client).
fn signed(
    cn: &str,
    hosts: Option<&[String]>,
    ca: &Certificate,
    ca_key: &KeyPair,
) -> Result<(String, String), CtlError> {
    let mut p = params(cn);
    p.key_usages = vec![KeyUsagePurpose::DigitalSignature, KeyUsagePurpose::KeyEncipherment];
    match hosts {
        Some(hosts) => {
            p.extended_key_usages = vec![ExtendedKeyUsagePurpose::ServerAuth];
            for host in hosts {
                let san = match host.parse::<std::net::IpAddr>() {
                    Ok(ip) => rcgen::SanType::IpAddress(ip),
                    Err(_) => rcgen::SanType::DnsName(
                        host.clone()
                            .try_into()
                            .map_err(|e| CtlError::Usage(format!("--host {host:?}: {e}")))?,
                    ),
                };
                p.subject_alt_names.push(san);
            }
        }
        None => p.extended_key_usages = vec![ExtendedKeyUsagePurpose::ClientAuth],
    }
    let key = KeyPair::generate().map_err(failed(cn))?;
    let cert = p.signed_by(&key, ca, ca_key).map_err(failed(cn))?;
    Ok((cert.pem(), key.serialize_pem()))
}

/// Writes `text` to a new file (never over an existing one), `mode`.
fn write_new(path: &Path, text: &str, mode: u32) -> Result<(), CtlError> {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(mode)
        .open(path)
        .map_err(|e| CtlError::Io(format!("{}: {e}", path.display())))?;
    f.write_all(text.as_bytes())
        .map_err(|e| CtlError::Io(format!("{}: {e}", path.display())))
}

pub fn run(dir: &Path, hosts: &[String], principals: &[String]) -> Result<(), CtlError> {
    let mut hosts: Vec<String> = hosts.to_vec();
    for always in ["127.0.0.1", "localhost"] {
        if !hosts.iter().any(|h| h == always) {
            hosts.push(always.to_owned());
        }
    }
    let mut names = vec!["ca".to_owned(), "gcud".to_owned()];
    names.extend(principals.iter().cloned());
    if let Some(twice) = names.iter().enumerate().find(|(i, n)| names[..*i].contains(n)) {
        return Err(CtlError::Usage(format!(
            "--principal {:?}: named twice, or the CA's or gcud's own name",
            twice.1
        )));
    }
    let paths = |name: &str| (dir.join(format!("{name}.crt")), dir.join(format!("{name}.key")));
    let taken: Vec<PathBuf> = names
        .iter()
        .flat_map(|n| {
            let (c, k) = paths(n);
            [c, k]
        })
        .filter(|p| p.exists())
        .collect();
    if let Some(first) = taken.first() {
        return Err(CtlError::Usage(format!(
            "{} exists: nothing written (tls init never overwrites; use another --dir)",
            first.display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(|e| CtlError::Io(format!("{}: {e}", dir.display())))?;
    let ca_key = KeyPair::generate().map_err(failed("the CA"))?;
    let mut ca_params = params("sagebrush gcud CA");
    ca_params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca_params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    let ca = ca_params.self_signed(&ca_key).map_err(failed("the CA"))?;
    let mut written = vec![("ca".to_owned(), ca.pem(), ca_key.serialize_pem())];
    written.push({
        let (cert, key) = signed("gcud", Some(&hosts), &ca, &ca_key)?;
        ("gcud".to_owned(), cert, key)
    });
    for name in principals {
        let (cert, key) = signed(name, None, &ca, &ca_key)?;
        written.push((name.clone(), cert, key));
    }
    for (name, cert, key) in &written {
        let (c, k) = paths(name);
        write_new(&c, cert, 0o644)?;
        write_new(&k, key, 0o600)?;
        println!("{}  {}", c.display(), k.display());
    }
    let d = dir.display();
    println!(
        "\ngcud.toml, on each listener to encrypt:\n  tls = {{ cert = \"{d}/gcud.crt\", key = \"{d}/gcud.key\", client_ca = \"{d}/ca.crt\" }}"
    );
    for name in principals {
        println!("[[principal]]\nname = \"{name}\"\npriority = 50   # and acts_for_users = true for a door");
    }
    Ok(())
}
