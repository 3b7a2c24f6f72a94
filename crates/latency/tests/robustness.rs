//! Property tests: no input makes the library panic; every error is a typed refusal, and every
//! delay it does return is finite with a finite, non-negative uncertainty.

use proptest::prelude::*;
use truepos_latency::{apply, estimate, Method, Options, Streams};

fn method(i: u8) -> Method {
    [Method::Auto, Method::Artefact, Method::Speeds, Method::Scan, Method::Inout][i as usize % 5]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, .. ProptestConfig::default() })]

    #[test]
    fn arbitrary_streams_never_panic(
        mt in prop::collection::vec(-1.0f64..1.0, 0..60),
        pt in prop::collection::vec(-1.0f64..1.0, 0..60),
        vals in prop::collection::vec(-0.5f64..0.5, 180),
        m in 0u8..5,
        sorted in any::<bool>(),
    ) {
        let mut mt = mt;
        let mut pt = pt;
        if sorted {
            mt.sort_by(f64::total_cmp);
            pt.sort_by(f64::total_cmp);
        }
        let mv: Vec<[f64; 3]> = (0..mt.len()).map(|i| [vals[i], vals[i + 60], vals[i + 120]]).collect();
        let pv: Vec<[f64; 3]> = (0..pt.len()).map(|i| [vals[i + 120], vals[i], vals[i + 60]]).collect();
        let s = Streams { machine_t: &mt, machine: &mv, probe_t: &pt, probe: &pv };
        let opt = Options {
            method: method(m),
            known_size: Some(truepos_latency::KnownSize::SphereDiameter(1.0)),
            max_delay: 0.01,
            ..Options::default()
        };
        if let Ok(e) = estimate(&s, &opt) {
            prop_assert!(e.delay.is_finite());
            prop_assert!(e.u_delay.is_finite() && e.u_delay >= 0.0);
        }
        let mut out = Vec::new();
        apply(&s, 0.001, &mut out);
        prop_assert_eq!(out.len(), pt.len());
    }
}
