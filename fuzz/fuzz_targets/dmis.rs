//! Fuzz target: the DMIS reader never panics on any text; an error names a line and column
//! inside the text; a parsed program prints to text that parses to the same statements (and
//! prints identically); the semantic check of a parsed program never panics, and a checked plan
//! runs on the dry-run machine without panicking.
#![no_main]

use libfuzzer_sys::fuzz_target;
use truepos_dmis::exec::{run, DryRun, RunOptions};
use truepos_dmis::{model, parse};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match parse("fuzz.dms", text) {
        Err(e) => {
            let lines = text.split('\n').count() as u32;
            assert!(e.pos.line >= 1 && e.pos.line <= lines + 1, "{e}");
            assert!(e.pos.col >= 1, "{e}");
        }
        Ok(p) => {
            let printed = p.print();
            let again = parse("printed.dms", &printed).expect("a printed program parses");
            assert_eq!(again.statements(), p.statements());
            assert_eq!(again.print(), printed);
            if let Ok(plan) = model::check(&p) {
                let opts = RunOptions::default();
                let mut m = DryRun::new(&plan, &opts);
                let _ = run(&plan, &mut m, &opts, &mut |_| {});
            }
        }
    }
});
