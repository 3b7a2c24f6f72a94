//! TLS for the PostgreSQL backend: libpq's `sslmode` values mapped onto a rustls client
//! configuration (ring provider, TLS 1.2 and 1.3; no system OpenSSL).
//!
//! | `sslmode`     | encrypted                       | server certificate checked            |
//! |---------------|---------------------------------|---------------------------------------|
//! | `disable`     | never                           | —                                     |
//! | `allow`, `prefer` (default) | when the server offers TLS | no (as libpq)              |
//! | `require`     | always (refused otherwise)      | no: protects against eavesdropping only, as libpq's `require` without a root certificate |
//! | `verify-ca`   | always                          | chain up to `sslrootcert`             |
//! | `verify-full` | always                          | chain up to `sslrootcert` and the host name (or IP address) of the address |
//!
//! `sslrootcert=FILE` names the PEM file of the trusted certificate authorities; without it,
//! `verify-ca`/`verify-full` use `~/.postgresql/root.crt` as libpq does. A missing, unreadable or
//! empty file is an input error naming the file, before any connection. `allow` is taken as
//! `prefer` (TLS first): never less protection than asked for.
//!
//! Entry points: [`SslMode`], [`TlsSettings::connector`].

use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::client::WebPkiServerVerifier;
use rustls::crypto::{verify_tls12_signature, verify_tls13_signature, CryptoProvider};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use rustls::{CertificateError, ClientConfig, DigitallySignedStruct, RootCertStore, SignatureScheme};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tokio_postgres_rustls::MakeRustlsConnect;

/// libpq's `sslmode` (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SslMode {
    /// Clear text only.
    Disable,
    /// TLS when the server offers it, else clear text (the default; `allow` means the same).
    Prefer,
    /// TLS required, certificate not verified.
    Require,
    /// TLS required, certificate chain verified against the trusted authorities.
    VerifyCa,
    /// As `VerifyCa`, and the certificate must name the host.
    VerifyFull,
}

impl SslMode {
    /// The `sslmode` value of an address (`allow` is taken as `prefer`).
    pub fn parse(v: &str) -> Result<SslMode, String> {
        Ok(match v {
            "disable" => SslMode::Disable,
            "allow" | "prefer" => SslMode::Prefer,
            "require" => SslMode::Require,
            "verify-ca" => SslMode::VerifyCa,
            "verify-full" => SslMode::VerifyFull,
            other => {
                return Err(format!(
                    "sslmode '{other}' is not one of disable, allow, prefer, require, verify-ca, verify-full"
                ))
            }
        })
    }

    /// The `sslmode` value as libpq spells it.
    pub fn name(self) -> &'static str {
        match self {
            SslMode::Disable => "disable",
            SslMode::Prefer => "prefer",
            SslMode::Require => "require",
            SslMode::VerifyCa => "verify-ca",
            SslMode::VerifyFull => "verify-full",
        }
    }

    /// Whether the server's certificate is checked against trusted authorities.
    pub fn verifies(self) -> bool {
        matches!(self, SslMode::VerifyCa | SslMode::VerifyFull)
    }

    /// The client library's mode: TLS tried first (`Prefer`) or required.
    pub fn client_mode(self) -> postgres::config::SslMode {
        match self {
            SslMode::Disable => postgres::config::SslMode::Disable,
            SslMode::Prefer => postgres::config::SslMode::Prefer,
            _ => postgres::config::SslMode::Require,
        }
    }
}

/// What a connection needs for TLS: the mode and, for the verifying modes, the trusted roots
/// (read when the address is parsed, so that a bad file is an input error before any motion).
#[derive(Clone)]
pub struct TlsSettings {
    /// libpq's `sslmode` of the address.
    pub mode: SslMode,
    /// The file the roots came from (for messages).
    pub root_cert: Option<PathBuf>,
    roots: Option<Arc<RootCertStore>>,
}

impl std::fmt::Debug for TlsSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "sslmode={}", self.mode.name())?;
        if let Some(p) = &self.root_cert {
            write!(f, " sslrootcert={}", p.display())?;
        }
        Ok(())
    }
}

impl TlsSettings {
    /// Settings for `mode`; `root_cert` is the `sslrootcert` parameter, `home` the user's home
    /// directory (for libpq's default `~/.postgresql/root.crt`).
    pub fn new(
        mode: SslMode,
        root_cert: Option<PathBuf>,
        home: Option<&Path>,
    ) -> Result<TlsSettings, String> {
        if !mode.verifies() {
            return Ok(TlsSettings { mode, root_cert, roots: None });
        }
        let path = match root_cert {
            Some(p) => p,
            None => match home {
                Some(h) => h.join(".postgresql/root.crt"),
                None => {
                    return Err(format!(
                        "sslmode={} needs the trusted certificate authorities: give sslrootcert=FILE (PEM)",
                        mode.name()
                    ))
                }
            },
        };
        if path.as_os_str() == "system" {
            return Err(
                "sslrootcert=system is not supported: give the PEM file of the authorities to trust".into()
            );
        }
        let roots = read_roots(&path)?;
        Ok(TlsSettings { mode, root_cert: Some(path), roots: Some(Arc::new(roots)) })
    }

    /// The rustls connector for these settings (`None` for `disable`).
    pub fn connector(&self) -> Option<MakeRustlsConnect> {
        if self.mode == SslMode::Disable {
            return None;
        }
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let chain = match &self.roots {
            Some(roots) if self.mode.verifies() => Some(
                WebPkiServerVerifier::builder_with_provider(roots.clone(), provider.clone()).build().ok()?,
            ),
            _ => None,
        };
        let verifier: Arc<dyn ServerCertVerifier> = Arc::new(ModeVerifier {
            provider: provider.clone(),
            chain,
            check_name: self.mode == SslMode::VerifyFull,
        });
        let config = ClientConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .ok()?
            .dangerous()
            .with_custom_certificate_verifier(verifier)
            .with_no_client_auth();
        Some(MakeRustlsConnect::new(config))
    }
}

/// The certificates of a PEM file; errors name the file.
fn read_roots(path: &Path) -> Result<RootCertStore, String> {
    let shown = path.display();
    let meta = std::fs::metadata(path).map_err(|e| format!("sslrootcert {shown}: {e}"))?;
    // A root file is a few kilobytes; a bound keeps a wrong path (a device, a dump) harmless.
    if !meta.is_file() || meta.len() > 4 << 20 {
        return Err(format!("sslrootcert {shown}: not a regular PEM file of at most 4 MiB"));
    }
    let mut store = RootCertStore::empty();
    let certs = CertificateDer::pem_file_iter(path).map_err(|e| format!("sslrootcert {shown}: {e}"))?;
    for (k, c) in certs.enumerate() {
        let c = c.map_err(|e| format!("sslrootcert {shown}: certificate {}: {e}", k + 1))?;
        store.add(c).map_err(|e| format!("sslrootcert {shown}: certificate {}: {e}", k + 1))?;
    }
    if store.is_empty() {
        return Err(format!(
            "sslrootcert {shown}: no PEM certificate (-----BEGIN CERTIFICATE-----) in the file"
        ));
    }
    Ok(store)
}

/// The server-certificate check of a mode. Always: the handshake's signatures are verified
/// with the certificate shown (the session is encrypted with that certificate's key). With
/// `chain` (`verify-ca`, `verify-full`): the certificate must lead to a trusted authority; with
/// `check_name` (`verify-full`) it must also name the address's host. Without `chain`
/// (`require`, `prefer`): the certificate itself is not checked, libpq's meaning.
#[derive(Debug)]
struct ModeVerifier {
    provider: Arc<CryptoProvider>,
    chain: Option<Arc<WebPkiServerVerifier>>,
    check_name: bool,
}

impl ServerCertVerifier for ModeVerifier {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        intermediates: &[CertificateDer<'_>],
        server_name: &ServerName<'_>,
        ocsp: &[u8],
        now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        let Some(chain) = &self.chain else { return Ok(ServerCertVerified::assertion()) };
        match chain.verify_server_cert(end_entity, intermediates, server_name, ocsp, now) {
            Err(rustls::Error::InvalidCertificate(
                CertificateError::NotValidForName | CertificateError::NotValidForNameContext { .. },
            )) if !self.check_name => Ok(ServerCertVerified::assertion()),
            other => other,
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        verify_tls12_signature(message, cert, dss, &self.provider.signature_verification_algorithms)
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        verify_tls13_signature(message, cert, dss, &self.provider.signature_verification_algorithms)
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.provider.signature_verification_algorithms.supported_schemes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse_as_libpq_names_them() {
        assert_eq!(SslMode::parse("allow").unwrap(), SslMode::Prefer);
        assert_eq!(SslMode::parse("verify-full").unwrap(), SslMode::VerifyFull);
        assert!(SslMode::parse("on").unwrap_err().contains("verify-full"));
        assert_eq!(SslMode::Require.client_mode(), postgres::config::SslMode::Require);
    }

    #[test]
    fn verifying_modes_need_a_readable_root_file() {
        let dir = tempfile::tempdir().unwrap();
        let e = TlsSettings::new(SslMode::VerifyFull, None, Some(dir.path())).unwrap_err();
        assert!(e.contains(".postgresql/root.crt"), "{e}");
        let empty = dir.path().join("empty.pem");
        std::fs::write(&empty, "not a certificate\n").unwrap();
        let e = TlsSettings::new(SslMode::VerifyCa, Some(empty.clone()), None).unwrap_err();
        assert!(e.contains("empty.pem") && e.contains("no PEM certificate"), "{e}");
        let e = TlsSettings::new(SslMode::VerifyCa, Some("/dev/zero".into()), None).unwrap_err();
        assert!(e.contains("/dev/zero") && e.contains("regular"), "{e}");
        let e = TlsSettings::new(SslMode::VerifyCa, None, None).unwrap_err();
        assert!(e.contains("sslrootcert=FILE"), "{e}");
        // Modes that do not verify need no file.
        assert!(TlsSettings::new(SslMode::Require, None, None).unwrap().connector().is_some());
        assert!(TlsSettings::new(SslMode::Disable, None, None).unwrap().connector().is_none());
    }

    #[test]
    fn a_generated_authority_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let ca = rcgen::generate_simple_self_signed(vec!["truepos test CA".into()]).unwrap();
        let pem = dir.path().join("ca.pem");
        std::fs::write(&pem, ca.cert.pem()).unwrap();
        let t = TlsSettings::new(SslMode::VerifyFull, Some(pem), None).unwrap();
        assert!(t.connector().is_some());
        assert_eq!(format!("{t:?}").split(' ').next(), Some("sslmode=verify-full"));
    }
}
