//! TLS on gcud's links and its clients' connections (rustls with ring;
//! ARCHITECTURE "Principals"): a server that may require a client
//! certificate from a private CA, whose subject CN names the principal; a
//! client that trusts a CA file and may present its own certificate.
//! Every file is PEM, and every error names the file.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rustls::server::WebPkiClientVerifier;
use rustls::{ClientConfig, RootCertStore, ServerConfig};
use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer, ServerName};
use tokio::net::TcpStream;
pub use tokio_rustls::{TlsAcceptor, TlsConnector, TlsStream, client, server};

/// A TLS set-up that cannot be made, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    #[error("{path}: {why}")]
    File { path: PathBuf, why: String },
    #[error("{0}")]
    Config(String),
}

fn provider() -> Arc<rustls::crypto::CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

fn certificates(path: &Path) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let bad = |why: String| TlsError::File {
        path: path.to_owned(),
        why,
    };
    let certs = CertificateDer::pem_file_iter(path)
        .map_err(|e| bad(format!("cannot read PEM certificates: {e}")))?
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| bad(format!("not PEM certificates: {e}")))?;
    if certs.is_empty() {
        return Err(bad("holds no PEM certificate (-----BEGIN CERTIFICATE-----)".into()));
    }
    Ok(certs)
}

fn private_key(path: &Path) -> Result<PrivateKeyDer<'static>, TlsError> {
    PrivateKeyDer::from_pem_file(path).map_err(|e| TlsError::File {
        path: path.to_owned(),
        why: format!("no PEM private key: {e}"),
    })
}

fn roots(path: &Path) -> Result<Arc<RootCertStore>, TlsError> {
    let mut store = RootCertStore::empty();
    for cert in certificates(path)? {
        store.add(cert).map_err(|e| TlsError::File {
            path: path.to_owned(),
            why: format!("not a CA certificate: {e}"),
        })?;
    }
    Ok(Arc::new(store))
}

/// A TLS server with `cert` and `key`; with `client_ca`, a client
/// certificate signed by it is required.
pub fn acceptor(cert: &Path, key: &Path, client_ca: Option<&Path>) -> Result<TlsAcceptor, TlsError> {
    let builder = ServerConfig::builder_with_provider(provider())
        .with_safe_default_protocol_versions()
        .map_err(|e| TlsError::Config(e.to_string()))?;
    let builder = match client_ca {
        Some(ca) => {
            let verifier = WebPkiClientVerifier::builder_with_provider(roots(ca)?, provider())
                .build()
                .map_err(|e| TlsError::File {
                    path: ca.to_owned(),
                    why: format!("cannot verify clients with it: {e}"),
                })?;
            builder.with_client_cert_verifier(verifier)
        }
        None => builder.with_no_client_auth(),
    };
    let config = builder
        .with_single_cert(certificates(cert)?, private_key(key)?)
        .map_err(|e| TlsError::File {
            path: key.to_owned(),
            why: format!("does not match {}: {e}", cert.display()),
        })?;
    Ok(TlsAcceptor::from(Arc::new(config)))
}

/// A TLS client trusting the CA in `ca`, presenting `identity` (its
/// certificate and key) when given.
pub fn connector(ca: &Path, identity: Option<(&Path, &Path)>) -> Result<TlsConnector, TlsError> {
    let builder = ClientConfig::builder_with_provider(provider())
        .with_safe_default_protocol_versions()
        .map_err(|e| TlsError::Config(e.to_string()))?
        .with_root_certificates(roots(ca)?);
    let config = match identity {
        Some((cert, key)) => builder
            .with_client_auth_cert(certificates(cert)?, private_key(key)?)
            .map_err(|e| TlsError::File {
                path: key.to_owned(),
                why: format!("does not match {}: {e}", cert.display()),
            })?,
        None => builder.with_no_client_auth(),
    };
    Ok(TlsConnector::from(Arc::new(config)))
}

/// The subject common name of a peer's certificate (the first of its chain).
pub fn peer_common_name(certs: Option<&[CertificateDer<'_>]>) -> Option<String> {
    let (_, cert) = x509_parser::parse_x509_certificate(certs?.first()?).ok()?;
    let cn = cert.subject().iter_common_name().next()?;
    cn.as_str().ok().map(str::to_owned)
}

/// The name a client checks the server's certificate against: the host
/// part of `host:port` (a DNS name or an IP address).
pub fn server_name(host_port: &str) -> Result<ServerName<'static>, TlsError> {
    let host = match host_port.rsplit_once(':') {
        Some((host, port)) if port.parse::<u16>().is_ok() => host,
        _ => host_port,
    };
    let host = host.trim_start_matches('[').trim_end_matches(']');
    ServerName::try_from(host.to_owned()).map_err(|e| TlsError::Config(format!("{host:?} names no TLS server: {e}")))
}

/// Connects to `host_port` over TCP, then TLS (checked against the host's name).
pub async fn connect(
    connector: &TlsConnector,
    host_port: &str,
    stream: TcpStream,
) -> io::Result<client::TlsStream<TcpStream>> {
    let name = server_name(host_port).map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e.to_string()))?;
    connector.connect(name, stream).await
}

/// The files a client of gcud connects with over TLS: the CA that signed
/// gcud's certificate, and this client's certificate and key (its
/// principal, by the certificate's subject CN).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClientFiles {
    pub ca: PathBuf,
    pub identity: Option<(PathBuf, PathBuf)>,
}

/// Where gcud listens, as its clients name it: `host:port` for plain TCP,
/// `tls://host:port` for TLS with [`ClientFiles`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Endpoint {
    /// `host:port`.
    pub addr: String,
    pub tls: Option<ClientFiles>,
}

/// The scheme of an [`Endpoint`] over TLS.
pub const TLS_SCHEME: &str = "tls://";

impl Endpoint {
    /// `text` (`host:port` or `tls://host:port`) with `files` for TLS:
    /// TLS needs them, plain TCP takes none.
    pub fn parse(text: &str, files: Option<ClientFiles>) -> Result<Self, String> {
        match (text.strip_prefix(TLS_SCHEME), files) {
            (Some(addr), Some(files)) => Ok(Endpoint {
                addr: addr.to_owned(),
                tls: Some(files),
            }),
            (Some(_), None) => Err(format!(
                "{text} is TLS: it needs the CA of gcud's certificate (and this client's certificate and key)"
            )),
            (None, Some(_)) => Err(format!(
                "TLS files are given but {text} is plain TCP: write tls://{text}"
            )),
            (None, None) => Ok(Endpoint {
                addr: text.to_owned(),
                tls: None,
            }),
        }
    }

    /// Connects: TCP, then TLS when configured (gcud's certificate checked
    /// against the CA and the host's name).
    pub async fn connect(&self) -> io::Result<Stream> {
        let tcp = crate::transport::connect_tcp(&self.addr).await?;
        let Some(files) = &self.tls else {
            return Ok(Stream::Plain(tcp));
        };
        let identity = files.identity.as_ref().map(|(c, k)| (c.as_path(), k.as_path()));
        let connector =
            connector(&files.ca, identity).map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e.to_string()))?;
        let tls = connect(&connector, &self.addr, tcp)
            .await
            .map_err(|e| io::Error::new(e.kind(), format!("TLS with {}: {e}", self.addr)))?;
        Ok(Stream::Tls(Box::new(tls)))
    }
}

impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.tls {
            Some(_) => write!(f, "{TLS_SCHEME}{}", self.addr),
            None => f.write_str(&self.addr),
        }
    }
}

impl From<&str> for Endpoint {
    /// A plain TCP endpoint.
    fn from(addr: &str) -> Self {
        Endpoint {
            addr: addr.to_owned(),
            tls: None,
        }
    }
}

impl From<String> for Endpoint {
    fn from(addr: String) -> Self {
        Endpoint { addr, tls: None }
    }
}

impl From<&String> for Endpoint {
    fn from(addr: &String) -> Self {
        Endpoint::from(addr.as_str())
    }
}

/// A connection to gcud, plain or TLS.
#[derive(Debug)]
pub enum Stream {
    Plain(TcpStream),
    Tls(Box<client::TlsStream<TcpStream>>),
}

impl tokio::io::AsyncRead for Stream {
    fn poll_read(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<io::Result<()>> {
        match self.get_mut() {
            Stream::Plain(s) => std::pin::Pin::new(s).poll_read(cx, buf),
            Stream::Tls(s) => std::pin::Pin::new(s.as_mut()).poll_read(cx, buf),
        }
    }
}

impl tokio::io::AsyncWrite for Stream {
    fn poll_write(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> std::task::Poll<io::Result<usize>> {
        match self.get_mut() {
            Stream::Plain(s) => std::pin::Pin::new(s).poll_write(cx, buf),
            Stream::Tls(s) => std::pin::Pin::new(s.as_mut()).poll_write(cx, buf),
        }
    }

    fn poll_flush(self: std::pin::Pin<&mut Self>, cx: &mut std::task::Context<'_>) -> std::task::Poll<io::Result<()>> {
        match self.get_mut() {
            Stream::Plain(s) => std::pin::Pin::new(s).poll_flush(cx),
            Stream::Tls(s) => std::pin::Pin::new(s.as_mut()).poll_flush(cx),
        }
    }

    fn poll_shutdown(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<io::Result<()>> {
        match self.get_mut() {
            Stream::Plain(s) => std::pin::Pin::new(s).poll_shutdown(cx),
            Stream::Tls(s) => std::pin::Pin::new(s.as_mut()).poll_shutdown(cx),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_server_name_is_the_host_of_host_port() {
        assert_eq!(server_name("gcu.example:4443").unwrap().to_str(), "gcu.example");
        assert_eq!(server_name("127.0.0.1:4443").unwrap().to_str(), "127.0.0.1");
        assert_eq!(server_name("[::1]:4443").unwrap().to_str(), "::1");
        assert!(server_name("bad name:1").is_err());
    }

    #[test]
    fn an_endpoint_is_tls_exactly_when_it_says_so() {
        let files = ClientFiles {
            ca: PathBuf::from("ca.crt"),
            identity: None,
        };
        let tls = Endpoint::parse("tls://gcu:4443", Some(files.clone())).unwrap();
        assert_eq!(
            (tls.addr.as_str(), tls.to_string().as_str()),
            ("gcu:4443", "tls://gcu:4443")
        );
        assert!(Endpoint::parse("tls://gcu:4443", None).is_err());
        assert!(Endpoint::parse("gcu:4001", Some(files)).is_err());
        assert_eq!(Endpoint::parse("gcu:4001", None).unwrap(), Endpoint::from("gcu:4001"));
    }

    #[test]
    fn a_missing_file_is_named() {
        let e = acceptor(
            Path::new("/nonexistent/gcud.crt"),
            Path::new("/nonexistent/gcud.key"),
            None,
        )
        .err()
        .unwrap();
        assert!(e.to_string().starts_with("/nonexistent/gcud.crt: "), "{e}");
    }
}
