//! TLS to a real PostgreSQL (a throw-away cluster with `ssl = on` and a certificate signed by a
//! test authority generated here): `sslmode=require` encrypts, `verify-full` checks the chain
//! and the address's host, `verify-ca` the chain only, a foreign authority and a server without
//! TLS are refused — each checked in the server's own connection log ("SSL enabled").
//! Without PostgreSQL installed each test prints `SKIPPED: …` and returns.

mod pgcluster;

use pgcluster::{Cluster, CELL_PW, OWNER_PW};
use truepos_audit::{now_utc, Audit, Db, Trail};
use truepos_somac::audit::{AuditSink, Event};

/// A certificate authority and a server certificate it signed for the IP address 127.0.0.1
/// (PEM: authority, server certificate, server key).
fn authority_and_server() -> (String, String, String) {
    use rcgen::{BasicConstraints, CertificateParams, CertifiedIssuer, DnType, IsCa, KeyPair};
    let mut ca = CertificateParams::new(Vec::<String>::new()).unwrap();
    ca.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    ca.distinguished_name.push(DnType::CommonName, "truepos test authority");
    let ca = CertifiedIssuer::self_signed(ca, KeyPair::generate().unwrap()).unwrap();
    let key = KeyPair::generate().unwrap();
    let mut server = CertificateParams::new(vec!["127.0.0.1".to_string()]).unwrap();
    server.distinguished_name.push(DnType::CommonName, "truepos test database");
    let cert = server.signed_by(&key, &ca).unwrap();
    (ca.pem(), cert.pem(), key.serialize_pem())
}

fn db(url: &str, user: &str) -> Result<Db, String> {
    let pw = if user == "owner" { OWNER_PW } else { CELL_PW };
    Db::parse_with(url, &|k| (k == "PGPASSWORD").then(|| pw.to_string())).map_err(|e| e.to_string())
}

/// Connection lines of the server log for `user`: (with TLS, without).
fn connections(c: &Cluster, user: &str) -> (usize, usize) {
    let log = c.log();
    let lines: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("connection authorized") && l.contains(&format!("user={user} ")))
        .collect();
    let tls = lines.iter().filter(|l| l.contains("SSL enabled")).count();
    (tls, lines.len() - tls)
}

fn record_a_run(db: &Db) -> Result<(), String> {
    let mut a = Audit::open(db, "tls.nc", &now_utc()).map_err(|e| e.to_string())?;
    a.record(&Event::Block { line: 1, text: "G1 X1".into(), time_s: 0.0 }).map_err(|e| e.to_string())?;
    a.commit().map_err(|e| e.to_string())
}

#[test]
fn tls_modes_encrypt_verify_and_refuse() {
    let (ca_pem, cert_pem, key_pem) = authority_and_server();
    let Some(c) = Cluster::start_tls(&cert_pem, &key_pem) else { return };
    let dir = tempfile::tempdir().unwrap();
    let ca = dir.path().join("ca.pem");
    std::fs::write(&ca, &ca_pem).unwrap();
    let (foreign_ca, _, _) = authority_and_server();
    let foreign = dir.path().join("foreign.pem");
    std::fs::write(&foreign, &foreign_ca).unwrap();
    let base = c.url("cell", "fleet");

    // The owner creates the schema over a verified connection.
    let full = format!("{}?sslmode=verify-full&sslrootcert={}", c.url("owner", "fleet"), ca.display());
    Trail::open(&db(&full, "owner").unwrap()).unwrap();
    assert_eq!(connections(&c, "owner"), (1, 0), "{}", c.log());

    // require: encrypted (the certificate is not checked: libpq's meaning).
    record_a_run(&db(&format!("{base}?sslmode=require"), "cell").unwrap()).unwrap();
    let after_require = connections(&c, "cell");
    assert!(after_require.0 >= 1 && after_require.1 == 0, "{after_require:?}\n{}", c.log());

    // verify-full against the right authority and the address in the certificate.
    let cell_full = format!("{base}?sslmode=verify-full&sslrootcert={}", ca.display());
    record_a_run(&db(&cell_full, "cell").unwrap()).unwrap();
    // The default (prefer) uses TLS when the server offers it.
    record_a_run(&db(&base, "cell").unwrap()).unwrap();
    let (tls, clear) = connections(&c, "cell");
    assert!(tls > after_require.0 && clear == 0, "({tls}, {clear})\n{}", c.log());
    let mut t = Trail::open(&db(&cell_full, "cell").unwrap()).unwrap();
    assert_eq!(t.runs().unwrap().len(), 3);

    // A foreign authority: refused, naming the certificate problem; nothing recorded.
    let bad = format!("{base}?sslmode=verify-full&sslrootcert={}", foreign.display());
    let e = record_a_run(&db(&bad, "cell").unwrap()).unwrap_err();
    assert!(e.to_lowercase().contains("certificate"), "{e}");
    eprintln!("refused: {e}");
    // The certificate names 127.0.0.1, not `localhost`: verify-full refuses the name, verify-ca
    // (chain only) accepts it. `localhost` may resolve to ::1 first, where nothing listens.
    let by_name = format!("postgresql://cell@localhost:{}/fleet", c.port);
    let e = record_a_run(
        &db(&format!("{by_name}?sslmode=verify-full&sslrootcert={}", ca.display()), "cell").unwrap(),
    )
    .unwrap_err();
    assert!(e.to_lowercase().contains("certificate"), "{e}");
    eprintln!("refused: {e}");
    record_a_run(&db(&format!("{by_name}?sslmode=verify-ca&sslrootcert={}", ca.display()), "cell").unwrap())
        .unwrap();
    let mut t = Trail::open(&db(&cell_full, "cell").unwrap()).unwrap();
    assert_eq!(t.runs().unwrap().len(), 4, "the refused connections recorded nothing");
    assert_eq!(connections(&c, "cell").1, 0, "no connection of the cell went in clear text");
}

#[test]
fn require_is_refused_by_a_server_without_tls() {
    let Some(c) = Cluster::start() else { return };
    let url = format!("{}?sslmode=require", c.url("cell", "fleet"));
    let e = record_a_run(&db(&url, "cell").unwrap()).unwrap_err();
    assert!(e.to_lowercase().contains("tls") || e.to_lowercase().contains("ssl"), "{e}");
    eprintln!("refused: {e}");
    // disable: the same server in clear text is fine (the schema is missing: the owner's
    // command is named, which proves the connection was made).
    let e = record_a_run(&db(&format!("{}?sslmode=disable", c.url("cell", "fleet")), "cell").unwrap())
        .unwrap_err();
    assert!(e.contains("truepos audit migrate"), "{e}");
}
