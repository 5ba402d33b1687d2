//! Ground truth for every experiment: Mitsuba 3 renders of a scene (two or more seeds, their
//! mean the reference and half their difference its noise), cached across runs, and the
//! mask of the pixels compared.
//!
//! # Caching
//! A render is reused when the scene exported for it (geometry, environment, camera, spp:
//! every file Mitsuba reads) is byte-identical to the one exported by the run that produced
//! it: Mitsuba is deterministic for a given seed, so rendering again would give the same
//! images.

use crate::{EvalError, Result};
use relight_render::compare;
use relight_render::raster::{self, RasterOptions};
use relight_render::{mitsuba, Image};
use relight_scene::scene::Scene;
use relight_scene::scene_file::SceneDesc;
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// The Python that runs Mitsuba 3, or an error saying how to install it.
///
/// # Errors
/// [`EvalError::Mitsuba`] when no Python can `import mitsuba`.
pub fn mitsuba_python() -> Result<PathBuf> {
    mitsuba::mitsuba_python().map_err(|e| {
        EvalError::Mitsuba(format!(
            "Mitsuba 3 is needed for `relight eval` (run scripts/setup.sh): {e}"
        ))
    })
}

/// A Mitsuba reference: the mean of its seeds, and its own noise.
#[derive(Clone, Debug)]
pub struct Reference {
    /// The per-seed renders.
    pub seeds: Vec<Image>,
    /// Their per-pixel mean: the reference.
    pub mean: Image,
    /// Half the relative RMSE between the first two seeds over the mask: the reference's
    /// relative noise (the error of their mean against the truth, for independent seeds).
    pub noise: f64,
    /// Half the mean absolute luminance error between the first two seeds: the reference's
    /// noise in the thesis' Table 5.1 metric (for Gaussian pixel noise of deviation `s` per
    /// seed, `E|Y_mean - Y_true| = (s / sqrt 2) sqrt(2 / pi)`, exactly this).
    pub lum_noise: f64,
}

/// What Mitsuba renders: `scene` at `spp` per seed and `max_depth` (2: direct only, -1:
/// unlimited), exported under `dir/name`, images `dir/name_s<seed>.exr`.
#[derive(Clone, Copy)]
pub struct Job<'a> {
    /// The Python that runs Mitsuba ([`mitsuba_python`]).
    pub python: &'a Path,
    /// The scene.
    pub scene: &'a Scene,
    /// The experiment's folder.
    pub dir: &'a Path,
    /// The export's name in it.
    pub name: &'a str,
    /// Samples per pixel per seed.
    pub spp: u32,
    /// Mitsuba's `max_depth`.
    pub max_depth: i32,
}

impl<'a> Job<'a> {
    /// The experiment's main reference: export `mitsuba` in `dir`.
    pub fn mitsuba(
        python: &'a Path,
        scene: &'a Scene,
        dir: &'a Path,
        spp: u32,
        max_depth: i32,
    ) -> Self {
        Job {
            python,
            scene,
            dir,
            name: "mitsuba",
            spp,
            max_depth,
        }
    }

    /// One render per seed, reusing the images of an identical earlier export (module docs).
    ///
    /// # Errors
    /// Export or Mitsuba failures naming the folder.
    pub fn render(&self, seeds: &[u32]) -> Result<Vec<Image>> {
        let (dir, name, spp) = (self.dir, self.name, self.spp);
        let export = dir.join(name);
        let before = folder_contents(&export);
        let failed =
            |e: &dyn std::fmt::Display| EvalError::Mitsuba(format!("{}: {e}", dir.display()));
        let json = mitsuba::export_mitsuba(self.scene, &export, spp, self.max_depth)
            .map_err(|e| failed(&e))?;
        let seed_path = |s: u32| dir.join(format!("{name}_s{s}.exr"));
        let reuse = !before.is_empty()
            && before == folder_contents(&export)
            && seeds.iter().all(|&s| seed_path(s).is_file());
        if reuse {
            eprintln!(
                "eval: {}: reusing the {spp}-spp renders of the identical exported scene",
                dir.display()
            );
            return seeds
                .iter()
                .map(|&s| relight_render::read_image(&seed_path(s)).map_err(|e| failed(&e)))
                .collect();
        }
        eprintln!(
            "eval: {}: Mitsuba 3, {spp} spp x {} seeds",
            dir.display(),
            seeds.len()
        );
        let (imgs, report) = mitsuba::render_mitsuba(self.python, &json, &export, seeds, None)
            .map_err(|e| failed(&e))?;
        eprintln!("eval: {}: {report}", dir.display());
        Ok(imgs)
    }

    /// Two seeds' renders as a [`Reference`] measured over `mask`.
    ///
    /// # Errors
    /// As [`Job::render`].
    pub fn reference(&self, seeds: [u32; 2], mask: &[bool]) -> Result<Reference> {
        let imgs = self.render(&seeds)?;
        let m = compare::metrics(&imgs[0], &imgs[1], Some(mask));
        Ok(Reference {
            mean: mean_image(&imgs[0], &imgs[1]),
            seeds: imgs,
            noise: m.rel_rmse / 2.0,
            lum_noise: m.mean_abs_lum_err / 2.0,
        })
    }
}

/// Every file of a folder (not recursive) by name; empty when it does not exist.
fn folder_contents(dir: &Path) -> BTreeMap<OsString, Vec<u8>> {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().is_file())
        .filter_map(|e| Some((e.file_name(), std::fs::read(e.path()).ok()?)))
        .collect()
}

/// The pixels of `scene`'s camera fully covered by geometry (4 x 4 supersampled coverage,
/// like Mitsuba's box filter): where methods are compared (the background is the
/// environment itself, not what a method computes).
pub fn coverage_mask(scene: &Scene) -> Vec<bool> {
    let ones = vec![glam::Vec3::ONE; scene.mesh.vertex_count()];
    raster::render_with(
        &scene.mesh,
        &scene.camera,
        &ones,
        None,
        &RasterOptions { supersample: 4 },
    )
    .full_coverage_mask()
}

/// Mean luminance of `img` over the pixels where `mask` is set (0 for an empty mask).
pub fn mean_lum(img: &Image, mask: &[bool]) -> f64 {
    let (s, n) = img
        .pixels
        .iter()
        .zip(mask)
        .filter(|(_, &m)| m)
        .fold((0.0, 0usize), |(s, n), (c, _)| {
            (s + compare::luminance(*c) as f64, n + 1)
        });
    if n == 0 {
        0.0
    } else {
        s / n as f64
    }
}

/// The per-pixel mean of two images of one size.
pub fn mean_image(a: &Image, b: &Image) -> Image {
    Image {
        width: a.width,
        height: a.height,
        pixels: a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| (*x + *y) * 0.5)
            .collect(),
    }
}

/// `desc` with its camera `width` pixels wide, the height keeping the aspect.
pub fn with_width(mut desc: SceneDesc, width: Option<u32>) -> SceneDesc {
    if let Some(w) = width {
        let c = &mut desc.camera;
        c.height = (w as u64 * c.height as u64 / c.width.max(1) as u64).max(1) as u32;
        c.width = w;
    }
    desc
}

/// File stem as a string (names of scenes and environments in tables).
pub fn stem(p: &Path) -> String {
    p.file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string()
}

/// The example scenes `names` of an experiment's defaults, in the folder `examples` (the
/// repository's `examples/`), each checked to exist.
///
/// # Errors
/// [`EvalError::Options`] naming the first scene not found and where it was looked for.
pub fn example_scenes(examples: &Path, names: &[&str]) -> Result<Vec<PathBuf>> {
    names
        .iter()
        .map(|name| {
            let p = examples.join(name);
            if p.is_file() {
                Ok(p)
            } else {
                Err(EvalError::Options(format!(
                    "{}: not found: the default experiments read relight's examples/ folder (run from the repository, pass --examples DIR, or give scenes)",
                    p.display()
                )))
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn width_keeps_the_aspect_and_mean_lum_ignores_masked_pixels() {
        let d: SceneDesc = serde_json::from_str(
            r#"{"shapes": [], "environment": {"type": "constant", "radiance": [1, 1, 1]},
                "camera": {"origin": [0, 0, 1], "target": [0, 0, 0], "up": [0, 1, 0],
                           "fov_deg": 40, "width": 256, "height": 192}}"#,
        )
        .unwrap();
        let c = with_width(d, Some(100)).camera;
        assert_eq!((c.width, c.height), (100, 75));
        let img = Image {
            width: 2,
            height: 1,
            pixels: vec![Vec3::ONE, Vec3::splat(100.0)],
        };
        assert!((mean_lum(&img, &[true, false]) - 1.0).abs() < 1e-6);
        assert_eq!(mean_lum(&img, &[false, false]), 0.0);
    }
}
