//! `halcmd` on the controller's host: reading and writing HAL pins of a running LinuxCNC (the
//! kinematics module's geometry pins), as the user that runs it.
//!
//! HAL lives in the controller's shared memory, so `halcmd` must run on the controller's host
//! ([`Hal::for_controller`] refuses an address that is not this host) and as the user that runs
//! LinuxCNC (found as the owner of its `milltask` process). truepos running as that user calls
//! `halcmd` directly; truepos running as root runs it through `runuser -u USER --`; any other
//! user is refused with the reason.
//!
//! `halcmd getp` prints seven significant digits: values are read to 0.5 µm below 1 m.

use std::path::PathBuf;
use std::process::Command;
use truepos_device::DeviceError;

/// How to run `halcmd` for one controller.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Hal {
    address: String,
    halcmd: PathBuf,
    /// `runuser` and the user, when this process is root and LinuxCNC runs as someone else.
    run_as: Option<(PathBuf, String)>,
}

fn find_program(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(
            ["/usr/local/sbin", "/usr/local/bin", "/usr/sbin", "/usr/bin", "/sbin", "/bin"]
                .map(PathBuf::from),
        )
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

fn real_uid_of(status: &str) -> Option<u32> {
    let line = status.lines().find(|l| l.starts_with("Uid:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The real uid of the first process named `comm`.
fn owner_of(comm: &str) -> Option<u32> {
    let rd = std::fs::read_dir("/proc").ok()?;
    for e in rd.flatten() {
        if !e.file_name().to_str().is_some_and(|s| s.bytes().all(|b| b.is_ascii_digit())) {
            continue;
        }
        if std::fs::read_to_string(e.path().join("comm")).map(|c| c.trim() == comm).unwrap_or(false) {
            if let Ok(st) = std::fs::read_to_string(e.path().join("status")) {
                return real_uid_of(&st);
            }
        }
    }
    None
}

fn user_name(uid: u32) -> Option<String> {
    let passwd = std::fs::read_to_string("/etc/passwd").ok()?;
    passwd.lines().find_map(|l| {
        let f: Vec<&str> = l.split(':').collect();
        (f.len() > 2 && f[2].parse::<u32>().ok() == Some(uid)).then(|| f[0].to_string())
    })
}

/// Whether `host` names this machine (loopback, or its host name).
pub fn is_local_host(host: &str) -> bool {
    let h = host.trim_matches(|c| c == '[' || c == ']');
    if h.eq_ignore_ascii_case("localhost") || h == "::1" || h.starts_with("127.") {
        return true;
    }
    let me = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    !me.trim().is_empty() && h.eq_ignore_ascii_case(me.trim())
}

impl Hal {
    /// `halcmd` for the LinuxCNC at `address` (`linuxcncrsh://HOST:PORT` without passwords) on
    /// `host`: this host only, as the user that runs it.
    pub fn for_controller(address: &str, host: &str) -> Result<Hal, DeviceError> {
        let rejected = |message: String| DeviceError::Rejected {
            address: address.to_string(),
            what: "reaching the controller's HAL (halcmd)".into(),
            message,
        };
        if !is_local_host(host) {
            return Err(rejected(format!(
                "halcmd works on the controller's own host, and `{host}` is not this one: run truepos on the controller's host"
            )));
        }
        let halcmd = find_program("halcmd").ok_or_else(|| rejected("halcmd is not installed here".into()))?;
        let owner = owner_of("milltask")
            .ok_or_else(|| rejected("no LinuxCNC (milltask) runs on this host".into()))?;
        let me = std::fs::read_to_string("/proc/self/status").ok().as_deref().and_then(real_uid_of);
        let run_as = if me == Some(owner) {
            None
        } else if me == Some(0) {
            let user = user_name(owner).ok_or_else(|| rejected(format!("no user name for uid {owner}")))?;
            let runuser =
                find_program("runuser").ok_or_else(|| rejected("runuser (util-linux) not found".into()))?;
            Some((runuser, user))
        } else {
            let user = user_name(owner).unwrap_or_else(|| format!("uid {owner}"));
            return Err(rejected(format!(
                "LinuxCNC runs as {user}: halcmd must run as that user (run truepos as {user})"
            )));
        };
        Ok(Hal { address: address.to_string(), halcmd, run_as })
    }

    /// The user halcmd runs as when it is not this process's.
    pub fn run_as(&self) -> Option<&str> {
        self.run_as.as_ref().map(|r| r.1.as_str())
    }

    /// Run `halcmd ARGS`; its stdout, or a [`DeviceError::Controller`] with its message.
    pub fn run(&self, args: &[&str], what: &str) -> Result<String, DeviceError> {
        let mut cmd = match &self.run_as {
            Some((runuser, user)) => {
                let mut c = Command::new(runuser);
                c.args(["-u", user, "--"]).arg(&self.halcmd);
                c
            }
            None => Command::new(&self.halcmd),
        };
        let out = cmd.args(args).output().map_err(|e| DeviceError::Controller {
            address: self.address.clone(),
            what: what.into(),
            message: format!("cannot run halcmd: {e}"),
        })?;
        let stdout = String::from_utf8_lossy(&out.stdout).to_string();
        if !out.status.success() {
            let err = String::from_utf8_lossy(&out.stderr);
            let said = [err.trim(), stdout.trim()].join(" ");
            return Err(DeviceError::Controller {
                address: self.address.clone(),
                what: what.into(),
                message: format!("halcmd {}: {}", args.join(" "), said.trim()),
            });
        }
        Ok(stdout)
    }

    /// The loaded components (`halcmd list comp`).
    pub fn components(&self) -> Result<Vec<String>, DeviceError> {
        Ok(self
            .run(&["list", "comp"], "listing the HAL components")?
            .split_whitespace()
            .map(str::to_string)
            .collect())
    }

    /// A pin's or parameter's value as a number.
    pub fn getp(&self, name: &str) -> Result<f64, DeviceError> {
        let what = format!("reading the HAL pin {name}");
        let s = self.run(&["getp", name], &what)?;
        let t = s.trim();
        match t {
            "TRUE" => Ok(1.0),
            "FALSE" => Ok(0.0),
            _ => t.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| DeviceError::Protocol {
                address: self.address.clone(),
                what,
                message: format!("halcmd getp printed `{t}`"),
            }),
        }
    }

    /// The signal a pin is linked to, if any (`halcmd show pin`).
    pub fn signal_of(&self, pin: &str) -> Result<Option<String>, DeviceError> {
        let s = self.run(&["show", "pin", pin], &format!("reading the HAL pin {pin}"))?;
        for l in s.lines() {
            let w: Vec<&str> = l.split_whitespace().collect();
            if let Some(k) = w.iter().position(|x| *x == pin) {
                if let (Some(arrow), Some(sig)) = (w.get(k + 1), w.get(k + 2)) {
                    if arrow.contains("==") {
                        return Ok(Some(sig.to_string()));
                    }
                }
                return Ok(None);
            }
        }
        Err(DeviceError::Protocol {
            address: self.address.clone(),
            what: format!("reading the HAL pin {pin}"),
            message: "halcmd show pin does not list it".into(),
        })
    }

    /// Set an input pin, or, when it is linked to a signal, that signal (`setp` / `sets`).
    /// Returns the HAL line that does it.
    pub fn set(&self, pin: &str, value: f64) -> Result<String, DeviceError> {
        let v = format!("{value:.6}");
        let line = match self.signal_of(pin)? {
            Some(sig) => vec!["sets".to_string(), sig, v],
            None => vec!["setp".to_string(), pin.to_string(), v],
        };
        let args: Vec<&str> = line.iter().map(String::as_str).collect();
        self.run(&args, &format!("writing the HAL pin {pin}"))?;
        Ok(line.join(" "))
    }
}

/// Whether `read` (seven significant digits, as halcmd prints) is `value`.
pub fn agrees(read: f64, value: f64) -> bool {
    (read - value).abs() <= 6e-7 * value.abs().max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_hosts_and_precision() {
        assert!(is_local_host("127.0.0.1") && is_local_host("localhost") && is_local_host("[::1]"));
        assert!(!is_local_host("192.0.2.7"));
        assert!(agrees(1234.568, 1234.56789) && agrees(10.03, 10.030000) && !agrees(10.03, 10.031));
        assert_eq!(real_uid_of("Name:\tx\nUid:\t1001\t0\t0\t0\n"), Some(1001));
    }
}
