//! # truepos-ippdme — I++ DME, the CMM line protocol
//!
//! I++ DME (version 1.4.3; later versions keep its framing) is how measuring software drives
//! coordinate measuring machines: ASCII lines on TCP port 1294, `TAG Command(args)` from the
//! client, `TAG &` / `TAG # data` / `TAG ! Error(..)` / `TAG %` from the server.
//!
//! Module map and entry points:
//! - [`protocol`]: tags, the call syntax ([`protocol::parse_line`]), responses
//!   ([`protocol::Response`]), the specification's error table ([`protocol::ErrorCode`]).
//! - [`command`]: typed commands ([`command::Command::from_call`]).
//! - [`reader`]: the bounded line reader (64 KiB per line).
//! - [`machine`]: the [`machine::Cmm`] trait — what a CMM behind the server must do.
//! - [`server`]: the session state machine ([`server::Session`]) and the TCP server
//!   ([`server::Server`]), generic over any [`machine::Cmm`].
//! - [`client`]: a CMM as a `truepos_device::ProbingMachine` ([`client::connect`]).
//! - [`part`]: the part file and the machine file's `[ippdme]` section.
//!
//! The virtual CMM that `truepos ippdme serve` puts behind the server lives in `truepos-cell`.

#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]

pub mod client;
pub mod command;
pub mod machine;
pub mod part;
pub mod protocol;
pub mod reader;
pub mod server;

pub use client::{connect, IppClient};
pub use machine::{Cmm, Contact, Guide, MachineError, ScanPath, ScanPoint, Stop};
pub use part::{MachineConfig, ModelConfig, Part, PartError};
pub use server::{Server, ServerHandle, Session};
