#![cfg(test)]
//! A method that exists only in the library's tests: traditional frameless rendering
//! with its own budget of 100K samples/s whatever the rate, registered with one line in
//! `methods/mod.rs` to show that this file and that line are all a new method needs.

use super::{frameless::Traditional, Budget, MethodInfo, MethodContext};

/// `test-frameless`.
pub const TEST_FRAMELESS: MethodInfo = MethodInfo {
    name: "test-frameless",
    description: "traditional frameless at its own 100K samples/s (a test of the registry)",
    budget: Budget::Own(|_| 100_000.0),
    check_rate: super::any_rate,
    build: |ctx| {
        let own = MethodContext {
            clock: crate::clock::Clock {
                rate: 100_000.0,
                ..ctx.clock
            },
            ..ctx.clone()
        };
        Ok(Box::new(Traditional::new(&own)))
    },
};

mod tests {
    use std::sync::Arc;

    use crate::{
        evaluation::{self, EvalConfig, Silent},
        methods::MethodKind,
        scene::builtin,
    };

    /// The registered test method runs through the whole evaluation by name and
    /// description alone: it is parsed, held to its own budget in every rate column, and
    /// shows exactly what traditional frameless shows at that budget.
    #[test]
    fn a_registered_method_runs_through_the_evaluation() {
        assert_eq!(
            MethodKind::parse("test-frameless"),
            Ok(MethodKind::TestFrameless)
        );
        let cfg = EvalConfig {
            scene_name: "toycar".into(),
            camera_path: None,
            start: 0.2,
            duration: 0.1,
            width: 32,
            height: 24,
            rates: vec![100_000.0, 400_000.0],
            methods: vec![MethodKind::TestFrameless, MethodKind::TraditionalFrameless],
            seed: 5,
            ideal_spp: 4,
            warmup: 0.2,
            refresh_hz: 60.0,
            max_depth: 3,
            cache_dir: None,
            strip_frames: Vec::new(),
            flip_every: 1,
        };
        let scene = Arc::new(builtin::load("toycar").expect("built-in scene"));
        let out = evaluation::run(scene, &cfg, &Silent).expect("evaluation runs");
        let row = |m: MethodKind, r: f64| {
            out.summary
                .results
                .iter()
                .find(|x| x.method == m && x.rate == r)
                .unwrap_or_else(|| panic!("no row for {m} at {r}"))
        };
        let reference = row(MethodKind::TraditionalFrameless, 100_000.0);
        for rate in [100_000.0, 400_000.0] {
            let t = row(MethodKind::TestFrameless, rate);
            assert_eq!(t.effective_rate, 100_000.0);
            assert_eq!(t.rms_mean, reference.rms_mean);
            assert_eq!(t.samples, reference.samples);
        }
        assert_ne!(
            row(MethodKind::TraditionalFrameless, 400_000.0).rms_mean,
            reference.rms_mean,
            "the rate changes traditional frameless, so the equality above is not trivial"
        );
        let json = serde_json::to_string(&out.summary).expect("serialises");
        assert!(json.contains("\"method\":\"test-frameless\""));
    }
}
