//! Per-pixel shading of the `cuts` method (Cheslack-Postava et al. 2008, sec. 4.2; the bake
//! is `relight_bake::cuts`).
//!
//! Deferred shading on [`raster::render_deferred`]: for every visible sample, the three
//! visibility cuts of its triangle's corners, interpolated with the sample's barycentric
//! weights, are merged in one traversal with the frame's illumination cut, and the sample's
//! material is evaluated at each merged cluster's direction
//! ([`relight_bake::cuts::merge::shade`], Eq. 5):
//! `B = sum_k |C'_k| <L O>_k (sum_j b_j <v_j>_k) f(<w>_k)`.
//!
//! The BRDF is the path tracer's: `Material::eval(wi, wo)` in the frame of the sample's
//! interpolated shading normal, `wi` towards the camera (`relight_render::pathtrace` uses the
//! same call). `eval` includes `max(0, cos theta_o)`; when the cuts already hold the cosine
//! ([`CutFunction::VisibilityCosine`], of the vertex normals) it is divided out, so the
//! cosine is counted once; with [`CutFunction::Visibility`] (binary visibility) `eval` is
//! used as it is, so the cosine follows the per-pixel normal. Materials are read at render
//! time from the scene (nothing of them is baked).

use crate::raster::{self, Fragment, RasterOptions, Rendered};
use glam::Vec3;
use relight_bake::cuts::light_cut::LightCut;
use relight_bake::cuts::merge::shade;
use relight_bake::cuts::visibility::CutFunction;
use relight_bake::cuts::CutsBake;
use relight_scene::camera::Camera;
use relight_scene::material::Material;
use relight_scene::mesh::TriMesh;
use relight_scene::scene::Environment;
use relight_sphere::warp::Frame;

/// Smallest `cos theta_o` at which the BRDF without its cosine is evaluated (directions
/// below are lifted to it; see [`CutsShader::shade_fragment`]).
const HORIZON: f32 = 1e-3;

/// The cuts renderer over one whole-mesh bake.
pub struct CutsShader<'a> {
    mesh: &'a TriMesh,
    materials: Vec<Material>,
    bake: &'a CutsBake,
    function: CutFunction,
}

impl<'a> CutsShader<'a> {
    /// A renderer of `bake` (one cut per vertex of `mesh`) with `materials` (indexed by
    /// `mesh.material_ids`; any materials: nothing of them is baked), whose cuts approximate
    /// `function`.
    ///
    /// # Panics
    /// If the bake does not hold one cut per vertex.
    pub fn new(
        mesh: &'a TriMesh,
        materials: Vec<Material>,
        bake: &'a CutsBake,
        function: CutFunction,
    ) -> Self {
        assert_eq!(
            bake.cuts.vertex_count(),
            mesh.vertex_count(),
            "one cut per vertex"
        );
        CutsShader {
            mesh,
            materials,
            bake,
            function,
        }
    }

    /// Outgoing radiance of fragment `f` towards the eye at `eye` under `light`. With cuts
    /// holding the cosine, a merged cluster whose mean direction is below the shading horizon
    /// still holds visible lights above it (the cut's mean says how much): its BRDF is
    /// evaluated at that direction lifted onto the horizon instead of dropping it.
    pub fn shade_fragment(&self, light: &LightCut, f: &Fragment, eye: Vec3) -> Vec3 {
        let frame = Frame::from_normal(f.shading_normal);
        let wi = frame.to_local((eye - f.position).normalize_or_zero());
        if wi.z <= 0.0 {
            return Vec3::ZERO; // one-sided materials, as the path tracer's
        }
        let material = self.materials[self.mesh.material_ids[f.tri as usize] as usize];
        let [a, b, c] = self.mesh.indices[f.tri as usize];
        let cuts = [a, b, c].map(|v| self.bake.cuts.cut(v as usize));
        let function = self.function;
        shade(&self.bake.tree, light, cuts, f.bary, |w| {
            let wo = frame.to_local(w);
            match function {
                CutFunction::VisibilityCosine => {
                    // A cluster straddling the horizon may have its mean direction below it
                    // while its visible lights (the cut's mean) are above: evaluate the BRDF
                    // at the direction lifted onto the horizon.
                    let wo = if wo.z >= HORIZON {
                        wo
                    } else {
                        Vec3::new(wo.x, wo.y, HORIZON).normalize()
                    };
                    material.eval(wi, wo) / wo.z
                }
                CutFunction::Visibility => material.eval(wi, wo),
            }
        })
    }

    /// Render `camera` under `light` (the environment drawn behind the objects if
    /// `background`).
    ///
    /// # Panics
    /// If `opts.supersample == 0` or the camera's image is empty.
    pub fn render(
        &self,
        light: &LightCut,
        camera: &Camera,
        background: Option<&Environment>,
        opts: &RasterOptions,
    ) -> Rendered {
        let eye = Vec3::from_array(camera.origin);
        raster::render_deferred(self.mesh, camera, background, opts, |f| {
            self.shade_fragment(light, f, eye)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relight_bake::cuts::light_cut::LightCut;
    use relight_bake::cuts::samples::sample_radiance;
    use relight_bake::cuts::{bake_range, CutsBakeSettings};
    use relight_scene::accel::{build, Backend};
    use relight_scene::shapes::ground_plane;
    use relight_sphere::EnvMap;

    /// A lone plane under a white sky, seen from above at 45 degrees, for `function`.
    fn plane_frame(material: Material, function: CutFunction) -> (Vec3, Vec3) {
        let mesh = ground_plane(Vec3::ZERO, 4.0, 4);
        let caster = build(&mesh, Backend::Bvh).unwrap();
        let settings = CutsBakeSettings {
            lights: 8192,
            function,
            ..Default::default()
        };
        let bake = bake_range(&mesh, caster.as_ref(), &settings, 0..mesh.vertex_count()).unwrap();
        let env = Environment::new(EnvMap::constant(Vec3::ONE));
        let radiance = sample_radiance(&bake.samples, &env).unwrap();
        let power: Vec<Vec3> = radiance
            .iter()
            .zip(&bake.samples.solid_angles)
            .map(|(&l, &w)| l * w)
            .collect();
        let light = LightCut::build(&bake.tree, &power, 2.0, 512).unwrap();
        let materials = [material];
        let shader = CutsShader::new(&mesh, materials.to_vec(), &bake, function);
        let camera = Camera {
            origin: [0.0, 2.0, 2.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_deg: 10.0,
            width: 8,
            height: 8,
        };
        let img = shader.render(&light, &camera, None, &RasterOptions::default());
        let mean = img.image.pixels.iter().copied().sum::<Vec3>() / 64.0;
        // The reference: the material's albedo towards the camera, by the leaf-level sum over
        // every light (no cut): sum_i L O_i eval(wi, w_i).
        let frame = Frame::from_normal(Vec3::Y);
        let wi = frame.to_local(Vec3::new(0.0, 1.0, 1.0).normalize());
        let exact: Vec3 = bake
            .samples
            .dirs
            .iter()
            .zip(&power)
            .map(|(&w, &p)| p * material.eval(wi, frame.to_local(w)))
            .sum();
        assert!(
            img.coverage.iter().all(|&c| c == 1.0),
            "the plane fills the frame"
        );
        (mean, exact)
    }

    #[test]
    fn lambert_plane_under_a_white_sky_reflects_its_albedo() {
        let lambert = Material::Lambert {
            albedo: Vec3::new(0.2, 0.5, 0.8),
        };
        for function in [CutFunction::VisibilityCosine, CutFunction::Visibility] {
            let (mean, exact) = plane_frame(lambert, function);
            // Exactly the albedo (Voronoi solid angles 4e-5 relative): rho / pi int cos = rho.
            assert!(
                (exact - lambert.diffuse_albedo()).length() < 1e-3,
                "{exact}"
            );
            // Measured 3e-5 with the cosine in the cuts (cut means of the cosine times
            // cluster means of L O, quantised), 1.3e-3 with binary visibility (the cosine is
            // then the BRDF's, sampled at the clusters' directions).
            assert!(
                (mean - exact).length() < 3e-3 * exact.length(),
                "{function:?}: {mean} vs {exact}"
            );
        }
    }

    #[test]
    fn ggx_plane_matches_the_sum_over_every_light() {
        let ggx = Material::GgxConductor {
            specular: Vec3::new(0.9, 0.6, 0.3),
            alpha: 0.3,
        };
        for function in [CutFunction::VisibilityCosine, CutFunction::Visibility] {
            let (mean, exact) = plane_frame(ggx, function);
            // The BRDF is sampled once per merged cluster (the paper's Eq. 5); at 512 light
            // nodes its lobe (alpha 0.3) spans a few clusters (measured: 1.6% with the cosine
            // in the cuts, divided out at the cluster's direction; 2e-5 with binary
            // visibility).
            assert!(
                (mean - exact).length() < 0.03 * exact.length(),
                "{function:?}: {mean} vs {exact}"
            );
        }
    }
}
