//! Fuzz target: every TOML configuration reader (bed, load case, scan features, CMM machine file)
//! either returns a value or an `InputError`-style error that names the file — never a panic.
//! The readers take paths (they report file, line and key), so each input is written to one
//! scratch file in the temporary directory first.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("truepos-fuzz-{}.toml", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    if std::fs::write(path, data).is_err() {
        return;
    }
    let name = path.display().to_string();
    if let Err(e) = truepos_comp::files::read_bed(path) {
        assert!(e.to_string().contains(&name), "bed error without the file: {e}");
    }
    if let Err(e) = truepos_comp::files::read_load(path) {
        assert!(e.to_string().contains(&name), "load error without the file: {e}");
    }
    let _ = truepos_scan::file::read_features(path, &truepos_scan::file::ParamOverrides::default());
    let _ = truepos_plant::scanning_cmm::read_machine_file(path);
});
