//! # truepos-io
//!
//! The edge layer of the interface contract (`shared/spec/interface.md`): reading the files
//! users hand to truepos and writing its outputs safely. No math lives here beyond parsing.
//!
//! Entry points:
//! - [`InputError`]: every problem with user input, naming file, line and column. The binary maps
//!   it to exit code 2.
//! - [`exit`]: the exit classes of this crate's errors (input 2, bad output path 2, write 3).
//! - [`csv::Table`]: a CSV file (leading `#` comments, one header row, any column order, unknown
//!   columns kept for pass-through), parsed in parallel, with typed column access.
//! - [`points`]: point files (`x_mm,y_mm,z_mm[,id]` CSV or NIST `.ds`).
//! - [`config::read_toml`]: TOML configuration into serde types, errors with line and column.
//! - [`atomic::AtomicFile`] / [`atomic::write_atomic`]: outputs written to a temporary file and
//!   renamed into place, so a failed run never leaves a partial file.
//! - [`csv::CsvWriter`]: fast CSV output with shortest round-trip float formatting (or fixed
//!   decimals), [`csv::format_rows_parallel`] for large outputs.
//! - [`num`]: exact fast float parsing, shortest round-trip and fixed-decimal formatting.
//! - [`stream::CsvStream`]: CSV in chunks with constant memory, reading and row indexing on a
//!   reader thread overlapped with work; [`stream::BackgroundWriter`] for the output side;
//!   [`stream::rewrite_points`]: a point file through a per-piece transform into an output of
//!   the same columns, streamed in constant memory whatever the formats (CSV, Parquet or E57
//!   in; CSV or Parquet out, by extension).
//! - [`parquet_file`]: Parquet point and stream files (same column names), read and written,
//!   whole or in batches ([`parquet_file::ParquetReader`], [`parquet_file::ParquetWriter`]).
//! - [`e57_file`]: E57 point clouds (ASTM E2807) as point files: every scan, in mm, invalid
//!   points skipped and counted.
//! - [`report::Report`]: a command's result as the contract's JSON and as human text (what
//!   the binary prints).
//! - [`xml::read_xml`]: XML inputs (QIF plans) with the same bounds plus nesting depth.
//! - [`limits`]: bounds on every input (file size, line length, binary data); [`limits::open_text`]
//!   for readers that stream text themselves.

#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]

pub mod atomic;
pub mod config;
pub mod csv;
pub mod e57_file;
pub mod error;
pub mod exit;
pub mod limits;
pub mod num;
pub mod parquet_file;
pub mod points;
pub mod report;
mod rewrite_binary;
pub mod stream;
pub mod xml;

pub use error::InputError;
