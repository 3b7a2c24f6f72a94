fn main() {
    let path = std::env::args().nth(1).unwrap();
    let part = std::env::args().nth(2).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let plan = truepos_dmis::model::check(&truepos_dmis::parse(&path, &text).unwrap()).unwrap();
    let mut opts = truepos_dmis::exec::RunOptions::default();
    for s in &plan.sensors { opts.sensors.insert(s.name.to_ascii_uppercase(), "Probe1".into()); }
    let cmm = truepos_cell::cmm::serve_loopback(Some(std::path::Path::new(&part)), None).unwrap();
    let mut client = truepos_ippdme::connect(&cmm.url).unwrap();
    match truepos_dmis::exec::run(&plan, &mut client, &opts, &mut |l| eprintln!("{l}")) {
        Ok(r) => { println!("{}", r.output.join("\n")); }
        Err(e) => { eprintln!("{e}"); }
    }
}
