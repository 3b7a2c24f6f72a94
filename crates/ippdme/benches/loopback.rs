//! Loopback throughput of the I++ DME server: PtMeas round trips per second (one command, wait
//! for `%`, next) and scan streaming points per second (ScanOnCircle with 0.01° steps, 36,001
//! points per scan). The machine behind the server is an ideal-plane CMM (no part), so the
//! figures measure the protocol, the session and the socket, not a part model.
//!
//! `cargo bench -p truepos-ippdme --bench loopback`

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use truepos_ippdme::{Cmm, Contact, MachineConfig, MachineError, ScanPath, ScanPoint, Server};
use truepos_math::{Point3, Vector3};

/// Ideal-plane machine: every probe touches the plane through the nominal point.
struct Plane {
    pos: Point3,
}

impl Cmm for Plane {
    fn describe(&self) -> String {
        "bench plane".into()
    }
    fn volume(&self) -> (Point3, Point3) {
        (Point3::new(-1000.0, -1000.0, -1000.0), Point3::new(1000.0, 1000.0, 1000.0))
    }
    fn home(&mut self) -> Result<Point3, MachineError> {
        self.pos = Point3::new(0.0, 0.0, 500.0);
        Ok(self.pos)
    }
    fn position(&self) -> Point3 {
        self.pos
    }
    fn move_to(&mut self, t: Point3, _: f64) -> Result<(), MachineError> {
        self.pos = t;
        Ok(())
    }
    fn probe(
        &mut self,
        _: Point3,
        _: Point3,
        r: f64,
        p: Point3,
        n: Vector3,
    ) -> Result<Option<Contact>, MachineError> {
        self.pos = p + n * r;
        Ok(Some(Contact { tip_center_mm: self.pos, normal: n }))
    }
    fn scan(
        &mut self,
        start: Contact,
        path: &ScanPath,
        _: f64,
        out: &mut Vec<ScanPoint>,
    ) -> Result<(), MachineError> {
        if let ScanPath::Circle { center, axis, delta_rad, step_rad } = *path {
            let n = ((delta_rad.abs() / step_rad).round() as usize).max(1);
            let arm = start.tip_center_mm - center;
            for k in 0..=n {
                let a = delta_rad * k as f64 / n as f64;
                let (s, c) = a.sin_cos();
                let v = arm * c + axis.cross(&arm) * s;
                out.push(ScanPoint { tip_center_mm: center + v, normal: v.normalize(), quality: 0.0 });
            }
        }
        Ok(())
    }
    fn stop(&mut self) {}
}

struct Conn {
    r: BufReader<TcpStream>,
    w: TcpStream,
    line: String,
}

impl Conn {
    /// Send and read to the `%`; returns the number of data lines.
    fn cmd(&mut self, text: &str) -> usize {
        self.w.write_all(text.as_bytes()).unwrap();
        let tag = &text[..5];
        let mut n = 0;
        loop {
            self.line.clear();
            self.r.read_line(&mut self.line).unwrap();
            if self.line.starts_with(tag) {
                match self.line.as_bytes()[6] {
                    b'%' => return n,
                    b'#' => n += 1,
                    b'!' => panic!("{}", self.line),
                    _ => {}
                }
            }
        }
    }
}

fn bench(c: &mut Criterion) {
    let config = MachineConfig::default();
    let h =
        Server::bind("127.0.0.1:0", Plane { pos: Point3::origin() }, &config, None).unwrap().spawn().unwrap();
    let s = TcpStream::connect(h.addr).unwrap();
    s.set_nodelay(true).unwrap();
    let mut conn = Conn { w: s.try_clone().unwrap(), r: BufReader::new(s), line: String::new() };
    for l in [
        "00001 StartSession()\r\n",
        "00002 Home()\r\n",
        "00003 ChangeTool(\"Probe1\")\r\n",
        "00004 OnPtMeasReport(X(), Y(), Z(), IJK())\r\n",
    ] {
        conn.cmd(l);
    }
    let mut g = c.benchmark_group("ippdme_loopback");
    g.throughput(Throughput::Elements(1));
    let mut k = 0u32;
    g.bench_function("ptmeas_round_trip", |b| {
        b.iter(|| {
            k = (k + 1) % 1000;
            let line = format!("00010 PtMeas(X({}), Y(2), Z(3), IJK(0,0,1))\r\n", k);
            assert_eq!(conn.cmd(&line), 1);
        })
    });
    conn.cmd("00011 OnScanReport(X(), Y(), Z(), IJK())\r\n");
    g.throughput(Throughput::Elements(36_001));
    g.sample_size(20);
    g.bench_function("scan_on_circle_36001_points", |b| {
        b.iter(|| {
            let lines = conn.cmd("00012 ScanOnCircle(0, 0, 0, 50, 0, 0, 0, 0, 1, 360, 0, 0.01)\r\n");
            assert!(lines >= 36_001 / 32);
        })
    });
    g.finish();
    conn.cmd("09999 EndSession()\r\n");
}

criterion_group!(benches, bench);
criterion_main!(benches);
