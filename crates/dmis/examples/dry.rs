fn main() {
    let path = std::env::args().nth(1).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let plan = truepos_dmis::model::check(&truepos_dmis::parse(&path, &text).unwrap()).unwrap();
    let opts = truepos_dmis::exec::RunOptions::default();
    let mut m = truepos_dmis::exec::DryRun::new(&plan, &opts);
    match truepos_dmis::exec::run(&plan, &mut m, &opts, &mut |l| eprintln!("{l}")) {
        Ok(r) => {
            for l in &r.motions { println!("{l}"); }
            println!("{}", r.output.join("\n"));
        }
        Err(e) => { eprintln!("{e}"); }
    }
}
