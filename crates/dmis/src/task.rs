//! `truepos dmis run` as library calls: read and check a program file ([`load`]), and where its
//! results go ([`output_path`]).

use crate::error::{DmisError, ErrorKind, Pos};
use crate::model::{check, Plan};
use std::path::{Path, PathBuf};

/// Read, parse and check the program at `path` (every problem located, exit 2).
pub fn load(path: &Path) -> Result<Plan, DmisError> {
    let name = path.display().to_string();
    // Bounded like every text input (size, line length, binary data; truepos_io::limits).
    let bytes = truepos_io::limits::read_text(path, "DMIS").map_err(|e| {
        let pos = Pos::new(e.line.unwrap_or(1) as u32, e.column.unwrap_or(1) as u32);
        DmisError::new(&name, pos, ErrorKind::Syntax, e.message)
    })?;
    let text = match String::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
            let line = 1 + good.iter().filter(|b| **b == b'\n').count() as u32;
            let col = 1 + String::from_utf8_lossy(
                &good[good.iter().rposition(|b| *b == b'\n').map_or(0, |k| k + 1)..],
            )
            .chars()
            .count() as u32;
            return Err(DmisError::new(&name, Pos::new(line, col), ErrorKind::Syntax, "not UTF-8 text"));
        }
    };
    check(&crate::parse(&name, &text)?)
}

/// The results file: `explicit`, else the file the program's `DEVICE/STOR` opened for output
/// names (relative to the program's folder), else `<program stem>_output.dms` beside it.
pub fn output_path(plan: &Plan, program: &Path, explicit: Option<&Path>) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    let dir = program.parent().unwrap_or(Path::new("."));
    match &plan.output_file {
        Some(f) => dir.join(f),
        None => {
            let stem = program
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| "program".into());
            dir.join(format!("{stem}_output.dms"))
        }
    }
}
