//! The controller address `linuxcncrsh://HOST:PORT[?password=…&enable=…]`.
//!
//! `password` is linuxcncrsh's connect password (its `--connectpw`, default `EMC`), `enable` its
//! enable password (`--enablepw`, default `EMCTOO`). Entry point: [`Address::parse`]; its
//! `Display` is the address without the passwords (what error messages and audit trails show).

use std::fmt;
use thiserror::Error;

/// linuxcncrsh's default connect password.
pub const DEFAULT_PASSWORD: &str = "EMC";
/// linuxcncrsh's default enable password.
pub const DEFAULT_ENABLE_PASSWORD: &str = "EMCTOO";
/// The URL scheme.
pub const SCHEME: &str = "linuxcncrsh://";

/// A parsed `linuxcncrsh://` address.
#[derive(Clone, PartialEq, Eq)]
pub struct Address {
    /// Host name or IP address of the linuxcncrsh server.
    pub host: String,
    /// TCP port of the linuxcncrsh server.
    pub port: u16,
    /// linuxcncrsh's connect password (`hello` command; never printed).
    pub password: String,
    /// linuxcncrsh's enable password (`set enable` command; never printed).
    pub enable_password: String,
}

impl fmt::Debug for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never print the passwords.
        write!(f, "Address({self})")
    }
}

/// Why an address is not a `linuxcncrsh://HOST:PORT` URL.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("`{url}` is not a linuxcncrsh address (linuxcncrsh://HOST:PORT[?password=…]): {reason}")]
pub struct AddressError {
    /// The address as given.
    pub url: String,
    /// What is wrong with it.
    pub reason: String,
}

impl Address {
    /// Parse `linuxcncrsh://HOST:PORT[?password=…&enable=…]`. HOST may be a name, an IPv4
    /// address or a bracketed IPv6 address.
    pub fn parse(url: &str) -> Result<Address, AddressError> {
        let err = |reason: &str| AddressError { url: url.to_string(), reason: reason.to_string() };
        let rest = url.strip_prefix(SCHEME).ok_or_else(|| err("it must begin with linuxcncrsh://"))?;
        let (hostport, query) = match rest.split_once('?') {
            Some((h, q)) => (h, Some(q)),
            None => (rest, None),
        };
        let hostport = hostport.strip_suffix('/').unwrap_or(hostport);
        let (host, port) = if let Some(h) = hostport.strip_prefix('[') {
            let (h, p) = h.split_once("]:").ok_or_else(|| err("an IPv6 host is written [ADDR]:PORT"))?;
            (h, p)
        } else {
            hostport.rsplit_once(':').ok_or_else(|| err("the port is missing"))?
        };
        if host.is_empty() {
            return Err(err("the host is missing"));
        }
        if host.contains(['/', '@', ' ']) {
            return Err(err("the host contains '/', '@' or a blank"));
        }
        let port: u16 = port.parse().map_err(|_| err("the port is not a number between 1 and 65535"))?;
        if port == 0 {
            return Err(err("the port is not a number between 1 and 65535"));
        }
        let mut a = Address {
            host: host.to_string(),
            port,
            password: DEFAULT_PASSWORD.into(),
            enable_password: DEFAULT_ENABLE_PASSWORD.into(),
        };
        if let Some(q) = query {
            for kv in q.split('&').filter(|s| !s.is_empty()) {
                let (k, v) = kv.split_once('=').ok_or_else(|| err("a query item is not key=value"))?;
                if v.is_empty() || v.contains(char::is_whitespace) {
                    return Err(err("a password is empty or contains blanks"));
                }
                match k {
                    "password" => a.password = v.to_string(),
                    "enable" => a.enable_password = v.to_string(),
                    _ => return Err(err(&format!("unknown query item `{k}` (password, enable)"))),
                }
            }
        }
        Ok(a)
    }

    /// `HOST:PORT` for connecting.
    pub fn socket_address(&self) -> String {
        if self.host.contains(':') {
            format!("[{}]:{}", self.host, self.port)
        } else {
            format!("{}:{}", self.host, self.port)
        }
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{SCHEME}{}", self.socket_address())
    }
}

impl truepos_math::exit::HasExitClass for AddressError {
    /// A malformed `--controller` address is bad usage (exit 2).
    fn exit_class(&self) -> truepos_math::exit::ExitClass {
        truepos_math::exit::ExitClass::Usage
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_host_port_and_passwords() {
        let a = Address::parse("linuxcncrsh://127.0.0.1:5007").unwrap();
        assert_eq!((a.host.as_str(), a.port), ("127.0.0.1", 5007));
        assert_eq!((a.password.as_str(), a.enable_password.as_str()), ("EMC", "EMCTOO"));
        assert_eq!(a.to_string(), "linuxcncrsh://127.0.0.1:5007");
        let a = Address::parse("linuxcncrsh://mill.local:6000/?password=secret&enable=more").unwrap();
        assert_eq!((a.host.as_str(), a.port), ("mill.local", 6000));
        assert_eq!((a.password.as_str(), a.enable_password.as_str()), ("secret", "more"));
        assert!(!format!("{a:?}").contains("secret"));
        let a = Address::parse("linuxcncrsh://[::1]:5007").unwrap();
        assert_eq!(a.socket_address(), "[::1]:5007");
    }

    #[test]
    fn rejects_what_is_not_an_address() {
        for bad in [
            "linuxcncrsh://127.0.0.1",
            "linuxcncrsh://:5007",
            "linuxcncrsh://host:0",
            "linuxcncrsh://host:70000",
            "linuxcncrsh://host:x",
            "ippdme://host:1294",
            "linuxcncrsh://host:5007?pw=1",
            "linuxcncrsh://host:5007?password=",
        ] {
            assert!(Address::parse(bad).is_err(), "{bad}");
        }
    }
}
