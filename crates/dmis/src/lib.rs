//! # truepos-dmis — DMIS part programs on any probing machine
//!
//! DMIS (ISO 22093, versions 3.0 to 5.x) is the language CMM part programs are written in. This
//! crate reads the prismatic subset `truepos dmis run` runs (listed in `docs/dmis.md`), checks
//! the whole program before anything moves, runs it on any
//! [`truepos_device::ProbingMachine`] (an I++ DME CMM, the virtual CMM) and writes the results.
//!
//! Layers and entry points:
//! - [`lexer`]: text → statements of tokens with line and column ([`lexer::statements`]).
//! - [`parse`](mod@parse): tokens → typed [`ast::Statement`]s ([`parse()`]); [`parse::Program::print`]
//!   prints them back in canonical DMIS (`parse(print(p)) == p`).
//! - [`model`]: the semantic model — units, sensors, nominal features, measurements,
//!   constructions, datums and coordinate systems, tolerances, outputs — checked before the first
//!   motion ([`model::check`]) into a [`model::Plan`] in internal units (mm, rad).
//! - [`exec`]: the plan run on a machine ([`exec::run`]): moves, probing with compensation, fits,
//!   constructions, coordinate systems, tolerance evaluation; `--dry-run` lists the motions.
//! - [`report`]: the DMIS output file and the JSON of a run.
//! - [`task`]: `truepos dmis run`'s file reading ([`task::load`]) and results path.
//! - [`uncertainty`]: what a task-specific uncertainty needs of a run: [`uncertainty::Replay`]
//!   (the plan again on the perfect features), [`uncertainty::parameters`], and the
//!   uncertainties per feature and tolerance in the JSON.
//!
//! Every problem in a program is a [`DmisError`] naming file, line and column (exit 2 in the
//! binary); a machine failure during the run is [`exec::RunError::Device`] naming the program line
//! (exit 3).

#![forbid(unsafe_code)]

pub mod ast;
pub mod error;
pub mod exec;
pub mod lexer;
pub mod model;
pub mod parse;
pub mod report;
pub mod task;
pub mod uncertainty;

pub use error::{DmisError, ErrorKind, Pos};
pub use parse::{parse, Program, Stmt};
