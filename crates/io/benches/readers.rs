//! The CSV readers' hand-written kernels against what a Rust user would use instead, in one run
//! (absolute times on a shared machine are noisy; compare the ratios):
//!
//! - `number/*`: one million short decimals (`-123.456789`, what a CMM writes), each read from
//!   the start of its field to its end: the SWAR kernel, the SSSE3 kernel, `fast-float2`'s
//!   `parse_partial` (the well-kept crate, also truepos's general path), and `memchr` to the
//!   delimiter plus `str::parse` (the standard library).
//! - `rows/*`: 300,000 `x,y,z` rows (one segment, one thread): the readers' loop with the SSSE3
//!   kernels, the same loop portable, and the obvious loop with `memchr` for the line ends and
//!   commas and `fast-float2` for the numbers; and the SSSE3 plain-row loop alone with its
//!   numbers converted by the SSSE3 kernel or by the portable SWAR one.
//!
//! - `write/*`: the other direction, one million values written with 6 decimals (what
//!   `--decimals 6` asks for): `num::write_fixed` (the integer route of `truepos_math::fixed`),
//!   std's `write!("{:.6}")`, and the shortest round-trip text (`zmij`, the default format).
//!
//! Run: `cargo bench -p truepos-io --bench readers`. The figures and the decision per kernel are
//! in docs/performance-io.md ("Hand-written kernels or crates").

// `criterion_group!` generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use truepos_io::csv::kernels;

/// A number reader: the value at the start of the text and the bytes it took.
type ReadNumber<'a> = &'a dyn Fn(&[u8]) -> Option<(f64, usize)>;

/// `n` numbers of the form `[-]ddd.dddddd` separated by commas, three to a line.
fn numbers(n: usize) -> Vec<u8> {
    let mut s = String::with_capacity(n * 12);
    let mut x: u64 = 0x2545_f491_4f6c_dd1d;
    for k in 0..n {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let v = (x % 2_000_000_000) as f64 / 1e6 - 1000.0;
        s.push_str(&format!("{v:.6}"));
        s.push(if k % 3 == 2 { '\n' } else { ',' });
    }
    // Padding so that every kernel may read its 24 bytes after the last number.
    s.push_str(&"0".repeat(32));
    s.into_bytes()
}

fn count_fields(text: &[u8]) -> usize {
    text.iter().filter(|&&c| c == b',' || c == b'\n').count()
}

fn bench_numbers(c: &mut Criterion) {
    let n = 1_000_000;
    let text = numbers(n);
    let body = &text[..text.len() - 32];
    let mut g = c.benchmark_group("number");
    g.throughput(Throughput::Elements(n as u64));
    g.sample_size(20);
    let walk = |read: ReadNumber| {
        let (mut i, mut sum) = (0, 0.0);
        while i < body.len() {
            let (v, used) = read(&text[i..]).expect("a short decimal");
            sum += v;
            i += used + 1;
        }
        sum
    };
    g.bench_function("swar", |b| b.iter(|| black_box(walk(&kernels::short_decimal_swar))));
    if kernels::short_decimal_ssse3(b"1.5,000000000000000000000000").is_some() {
        g.bench_function("ssse3", |b| b.iter(|| black_box(walk(&kernels::short_decimal_ssse3))));
    }
    g.bench_function("fast_float2", |b| {
        b.iter(|| black_box(walk(&|t: &[u8]| fast_float2::parse_partial::<f64, _>(t).ok())))
    });
    g.bench_function("memchr_std_parse", |b| {
        b.iter(|| {
            black_box(walk(&|t: &[u8]| {
                let e = memchr::memchr2(b',', b'\n', t)?;
                Some((std::str::from_utf8(&t[..e]).ok()?.parse::<f64>().ok()?, e))
            }))
        })
    });
    g.finish();
    assert_eq!(count_fields(body), n);
}

fn bench_rows(c: &mut Criterion) {
    let rows = 300_000;
    let text = numbers(3 * rows);
    let seg = &text[..text.len() - 32];
    let mut g = c.benchmark_group("rows");
    g.throughput(Throughput::Bytes(seg.len() as u64));
    g.sample_size(20);
    let mut out = Vec::with_capacity(rows);
    g.bench_function("truepos_ssse3", |b| {
        b.iter(|| {
            out.clear();
            assert_eq!(kernels::rows3(seg, true, &mut out), Some(rows));
            black_box(out.len())
        })
    });
    // The plain-row loop alone (stops short of the segment's end), its numbers by the SSSE3
    // kernel or by the portable SWAR one: does the SSSE3 number kernel earn its place?
    let plain = kernels::plain_rows3(seg, false, &mut out);
    out.clear();
    if let Some(n) = plain {
        assert!(n + 8 >= rows, "{n} of {rows} rows plain");
        for (name, swar) in [("plain_loop_ssse3_numbers", false), ("plain_loop_swar_numbers", true)] {
            g.bench_function(name, |b| {
                b.iter(|| {
                    out.clear();
                    assert_eq!(kernels::plain_rows3(seg, swar, &mut out), Some(n));
                    black_box(out.len())
                })
            });
        }
    }
    g.bench_function("truepos_portable", |b| {
        b.iter(|| {
            out.clear();
            assert_eq!(kernels::rows3(seg, false, &mut out), Some(rows));
            black_box(out.len())
        })
    });
    g.bench_function("memchr_fast_float2", |b| {
        b.iter(|| {
            out.clear();
            for line in memchr::Memchr::new(b'\n', seg).scan(0, |start, end| {
                let l = &seg[*start..end];
                *start = end + 1;
                Some(l)
            }) {
                let mut d = [0.0; 3];
                let mut it = line.split(|&c| c == b',');
                for v in &mut d {
                    *v = fast_float2::parse(it.next().expect("3 fields")).expect("a number");
                }
                out.push(d);
            }
            assert_eq!(out.len(), rows);
            black_box(out.len())
        })
    });
    g.finish();
}

fn bench_write(c: &mut Criterion) {
    use std::io::Write;
    use truepos_io::num::{write_fixed, write_shortest};
    let n = 1_000_000;
    let mut x: u64 = 0x2545_f491_4f6c_dd1d;
    let values: Vec<f64> = (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % 2_000_000_000_000) as f64 / 1e9 - 1000.0
        })
        .collect();
    let mut g = c.benchmark_group("write");
    g.throughput(Throughput::Elements(n as u64));
    g.sample_size(20);
    let mut out = Vec::with_capacity(n * 16);
    g.bench_function("fixed6_truepos", |b| {
        b.iter(|| {
            out.clear();
            for &v in &values {
                write_fixed(black_box(v), 6, &mut out);
                out.push(b',');
            }
            out.len()
        })
    });
    g.bench_function("fixed6_std_write", |b| {
        b.iter(|| {
            out.clear();
            for &v in &values {
                let _ = write!(out, "{:.6}", black_box(v));
                out.push(b',');
            }
            out.len()
        })
    });
    g.bench_function("shortest_zmij", |b| {
        b.iter(|| {
            out.clear();
            for &v in &values {
                write_shortest(black_box(v), &mut out);
                out.push(b',');
            }
            out.len()
        })
    });
    g.finish();
}

criterion_group!(benches, bench_numbers, bench_rows, bench_write);
criterion_main!(benches);
