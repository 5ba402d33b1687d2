//! Green 2005 Fig. 3-4 and 3-5, small: `relight eval --method sg` against
//! Mitsuba 3. Skips when ../shared or Mitsuba is absent.
//!
//! Asserted (tolerances measured at these settings, see docs/RESULTS.md, sg, for the full run):
//! * Fig. 3-4: the SG render of a GGX conductor (with interreflections) and of a GGX plastic
//!   (direct) is within `TOL_34` relative RMSE of Mitsuba. Against a 512-spp reference the SG
//!   error itself is 22 % (conductor: one lobe smooths the windows' reflections) and 11 %
//!   (plastic); at these 64 spp x 2 seeds the reference adds 16 % / 12 % of noise (printed),
//!   which combine in quadrature to about 27 % / 16 % (measured 22.9 % / 14.9 %). 30 % leaves
//!   a few points for run-to-run noise and fails on any real regression of the fit, the view
//!   or triangle interpolation or the prefiltered lookup.
//! * Fig. 3-5: where visibility matters (the pixels where the bakes with and without
//!   visibility differ), SG's error is under half the no-visibility baseline's, and over the
//!   whole image SG is better: prefiltered environment mapping shows the highlights the teapot
//!   blocks.

mod common;

/// Relative RMSE bound of Fig. 3-4 at 64 spp, 96 pixels wide.
const TOL_34: f64 = 0.30;

#[test]
fn sg_renders_match_mitsuba_and_beat_environment_mapping_in_shadow() {
    if !common::can_evaluate() {
        return;
    }
    let cwd = common::tmpdir("eval", "sg");
    let out = cwd.join("out");
    let rows = common::eval_rows(
        &cwd,
        &out,
        &[
            "--method",
            "sg",
            "--examples",
            common::examples().to_str().unwrap(),
            "--spp",
            "64",
            "--width",
            "96",
            "--indirect-paths",
            "16",
            // Fig. 3-4 and 3-5 (the fourth default experiment, the teapot, is checked
            // at test size by relight-render's `more_direct_lobes_are_never_worse`).
            "--experiments",
            "fig3-4_conductor,fig3-4_plastic,fig3-5_shadowed_highlight",
        ],
    );
    assert_eq!(rows.len(), 3, "three experiments");
    for r in rows {
        let name = r["experiment"].as_str().unwrap();
        let e = r["rel_rmse"].as_f64().unwrap();
        let noise = r["reference_noise"].as_f64().unwrap();
        eprintln!("{name}: relative RMSE {e:.4} (reference noise {noise:.4})");
        if name.starts_with("fig3-4") {
            assert!(e < TOL_34, "{name}: relative RMSE {e} >= {TOL_34}");
        } else {
            let b = r["baseline_rel_rmse"].as_f64().unwrap();
            let es = r["sg_rel_rmse_shadowed"].as_f64().unwrap();
            let bs = r["baseline_rel_rmse_shadowed"].as_f64().unwrap();
            let px = r["shadowed_pixels"].as_u64().unwrap();
            eprintln!("  no-visibility {b:.4}; where visibility matters ({px} px): SG {es:.4}, no-visibility {bs:.4}");
            assert!(px > 50, "too few pixels where visibility matters: {px}");
            assert!(
                es < 0.5 * bs,
                "SG {es} not under half of environment mapping's {bs}"
            );
            assert!(e < b, "SG {e} not better than environment mapping {b}");
        }
    }
    let _ = std::fs::remove_dir_all(&cwd);
}
