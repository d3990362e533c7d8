//! What held each method's new images back, in words: its image build against the
//! refresh period, read from the figures its pipeline reports (a run's `pipeline` in
//! `summary.json`), so that a live table names its first bottleneck instead of leaving
//! it to be worked out from the figures.

use serde_json::Value;

use super::LiveRun;

/// The share of the refresh rate at which a method's new images keep up (the bar the
/// live tables are held to).
const KEEPS_UP: f64 = 0.97;

/// The image build's steps a sentence names, the largest first.
const STEPS_NAMED: usize = 3;

/// One run's image build, from its pipeline's figures.
#[derive(Debug, PartialEq)]
pub(super) struct Build {
    /// New images shown a second.
    pub new_images_per_s: f64,
    /// Mean and 95th percentile of a build's wall time, milliseconds (the warm-up
    /// included, as the pipeline counts them).
    pub mean_ms: f64,
    pub p95_ms: f64,
    /// Threads of the build's pool.
    pub threads: u64,
    /// The steps of a build that took time, by name, mean milliseconds, the largest
    /// first (only a method that reports them: adaptive's `pass_ms`).
    pub steps: Vec<(String, f64)>,
    /// How old the newest sample a build had was at its refresh, and how long before
    /// that refresh the build began, mean milliseconds (only a method that reports
    /// them: adaptive's `sample_lag_ms_mean` and `lead_ms_mean`).
    pub lag: Option<(f64, f64)>,
}

impl Build {
    /// `run`'s build; `None` where its summary holds no build figures (written before
    /// the pipeline reported them).
    pub(super) fn of(run: &LiveRun) -> Option<Build> {
        let p = &run.pipeline;
        let number = |key: &str| p.get(key).and_then(Value::as_f64).filter(|v| v.is_finite());
        let mut steps: Vec<(String, f64)> = p
            .get("pass_ms")
            .and_then(Value::as_object)
            .map(|m| {
                m.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.as_f64()?)))
                    .filter(|(_, ms)| ms.is_finite() && *ms > 0.0)
                    .collect()
            })
            .unwrap_or_default();
        steps.sort_by(|a, b| b.1.total_cmp(&a.1).then_with(|| a.0.cmp(&b.0)));
        Some(Build {
            new_images_per_s: run.scores.live.images_per_s,
            mean_ms: number("reconstruct_ms_mean")?,
            p95_ms: number("reconstruct_ms_p95")?,
            threads: p.get("recon_threads").and_then(Value::as_u64).unwrap_or(1),
            steps,
            lag: number("sample_lag_ms_mean").zip(number("lead_ms_mean")),
        })
    }

    /// What held the new images back at `refresh_hz`, in a sentence (or that nothing
    /// did).
    pub(super) fn sentence(&self, refresh_hz: f64) -> String {
        let period = 1e3 / refresh_hz;
        let took = format!(
            "its image build took {:.1} ms on average ({:.1} at the 95th percentile) on {} \
             thread{}",
            self.mean_ms,
            self.p95_ms,
            self.threads,
            if self.threads == 1 { "" } else { "s" }
        );
        let shown = format!(
            "{:.1} new images a second of {refresh_hz}",
            self.new_images_per_s
        );
        let keeps_up = self.new_images_per_s >= KEEPS_UP * refresh_hz;
        let verdict = if keeps_up {
            format!("keeps up ({shown}); {took}, within the {period:.1} ms refresh period")
        } else if self.mean_ms > period {
            format!(
                "{shown}: {took}, longer than the {period:.1} ms refresh period, so the \
                 image build is the first bottleneck"
            )
        } else if self.p95_ms > period {
            format!(
                "{shown}: {took}; within the {period:.1} ms refresh period on average, but \
                 its slowest builds are longer and miss their refreshes"
            )
        } else {
            format!(
                "{shown}: {took}, within the {period:.1} ms refresh period, so something \
                 else holds its images back (its samples, or other work on the machine)"
            )
        };
        let verdict = match self.largest_steps().filter(|_| !keeps_up) {
            Some(steps) => format!("{verdict}; its largest steps: {steps}"),
            None => verdict,
        };
        match self.lag {
            Some((lag, lead)) => format!(
                "{verdict}; the newest sample it had was {lag:.1} ms old at its refresh \
                 (the build began {lead:.1} ms before it)"
            ),
            None => verdict,
        }
    }

    /// The largest steps as "name ms, …", if the method reports its steps.
    fn largest_steps(&self) -> Option<String> {
        let named: Vec<String> = self
            .steps
            .iter()
            .take(STEPS_NAMED)
            .map(|(name, ms)| format!("{name} {ms:.1} ms"))
            .collect();
        (!named.is_empty()).then(|| named.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn build(new: f64, mean: f64, p95: f64) -> Build {
        Build {
            new_images_per_s: new,
            mean_ms: mean,
            p95_ms: p95,
            threads: 1,
            steps: vec![
                ("history".into(), 14.4),
                ("resolve".into(), 13.3),
                ("carry".into(), 10.7),
                ("splat".into(), 10.0),
            ],
            lag: None,
        }
    }

    /// Each case of the verdict at 30 Hz (a 33.3 ms period): keeping up, a build longer
    /// than the period, slow builds only, and a build that fits while images lag.
    #[test]
    fn the_sentence_names_what_held_the_images_back() {
        let keeps = build(29.3, 21.3, 25.6).sentence(30.0);
        assert!(
            keeps.starts_with("keeps up (29.3 new images a second of 30)"),
            "{keeps}"
        );
        assert!(!keeps.contains("largest steps"), "{keeps}");
        let slow = build(22.7, 48.8, 78.2).sentence(30.0);
        assert!(
            slow.contains("longer than the 33.3 ms refresh period"),
            "{slow}"
        );
        assert!(
            slow.contains("the image build is the first bottleneck"),
            "{slow}"
        );
        assert!(
            slow.ends_with("its largest steps: history 14.4 ms, resolve 13.3 ms, carry 10.7 ms"),
            "{slow}"
        );
        let tail = build(27.0, 26.9, 41.5).sentence(30.0);
        assert!(tail.contains("slowest builds are longer"), "{tail}");
        let other = build(15.7, 3.0, 8.0).sentence(30.0);
        assert!(
            other.contains("something else holds its images back"),
            "{other}"
        );
        // Exactly at the bar keeps up.
        assert!(build(0.97 * 30.0, 40.0, 50.0)
            .sentence(30.0)
            .starts_with("keeps up"));
    }

    /// A run's build is read from its pipeline figures, the steps largest first
    /// without the empty ones; a summary without the figures gives none.
    #[test]
    fn a_build_is_read_from_the_pipeline_figures() {
        let pipeline = serde_json::json!({
            "reconstruct_ms_mean": 48.8,
            "reconstruct_ms_p95": 78.2,
            "recon_threads": 2,
            "pass_ms": {"carry": 10.7, "gpu_wait": 0.0, "history": 14.4, "filters": 3.0}
        });
        let mut run = super::super::tests::a_run(pipeline);
        run.scores.live.images_per_s = 20.0;
        let b = Build::of(&run).expect("figures");
        assert_eq!((b.mean_ms, b.p95_ms, b.threads), (48.8, 78.2, 2));
        let names: Vec<&str> = b.steps.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["history", "carry", "filters"]);
        assert!(b.sentence(30.0).contains("on 2 threads"));
        assert!(!b.sentence(30.0).contains("newest sample"));
        run.pipeline["sample_lag_ms_mean"] = 14.04.into();
        run.pipeline["lead_ms_mean"] = 12.76.into();
        let b = Build::of(&run).expect("figures");
        assert_eq!(b.lag, Some((14.04, 12.76)));
        assert!(
            b.sentence(30.0).ends_with(
                "the newest sample it had was 14.0 ms old at its refresh (the build began \
                 12.8 ms before it)"
            ),
            "{}",
            b.sentence(30.0)
        );
        run.pipeline = serde_json::json!({"reconstruct_ms_p95": 78.2});
        assert_eq!(Build::of(&run), None);
    }
}
