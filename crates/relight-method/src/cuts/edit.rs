//! Material edits of a `cuts` bake after baking (`--material`): nothing of the materials is
//! baked, so a material may replace every surface's ([`CutsFrameSettings::material`]) or one
//! named object's. An object's edit appends the material (with its maps) to the scene and
//! points the object's triangles at it; the other objects keep theirs.

use super::frame::{load_override_maps, CutsFrameSettings, MaterialOverride};
use crate::{Baked, MethodError};
use relight_scene::material::maps::SceneMaps;
use std::collections::HashSet;
use std::sync::Arc;

/// One `--material` of the command line: a material for every surface (`object` `None`) or
/// for the object of that name.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialEdit {
    /// The object it edits (`None`: every surface).
    pub object: Option<String>,
    /// The material and where it came from.
    pub material: MaterialOverride,
}

/// Parse `--material`: `NAME=MATERIAL` edits object NAME, a bare `MATERIAL` (inline JSON or
/// a .json file, as [`crate::parse_material_override`] reads it) every surface. Text that
/// starts with `{` or names an existing file is a bare material even when it holds `=`.
pub fn parse_material_edit(text: &str) -> Result<MaterialEdit, String> {
    let bare = text.trim_start().starts_with('{') || std::path::Path::new(text).is_file();
    match text.split_once('=') {
        Some((name, material)) if !bare => {
            if name.is_empty() {
                return Err(format!("{text}: NAME=MATERIAL with an empty NAME"));
            }
            Ok(MaterialEdit {
                object: Some(name.to_string()),
                material: crate::parse_material_override(material)
                    .map_err(|e| format!("object {name:?}: {e}"))?,
            })
        }
        _ => Ok(MaterialEdit {
            object: None,
            material: crate::parse_material_override(text)?,
        }),
    }
}

/// Apply the edits of `s.materials` (taking them out): a bare one becomes
/// [`CutsFrameSettings::material`], the named ones edit `baked`'s scene (each object's
/// triangles pointed at a new material with its maps).
///
/// # Errors
/// [`MethodError::Settings`] for an unknown object (the message lists the names), an object
/// named twice, a bare material given with named ones or twice, edits of a bake other than
/// `cuts`, or maps that cannot be read or applied (the message names the file).
pub fn apply_material_edits(
    baked: &mut Baked,
    s: &mut CutsFrameSettings,
) -> Result<(), MethodError> {
    let edits = std::mem::take(&mut s.materials);
    if edits.is_empty() {
        return Ok(());
    }
    let bad = |m: String| Err(MethodError::Settings(m));
    let (mut bare, named): (Vec<MaterialEdit>, Vec<MaterialEdit>) =
        edits.into_iter().partition(|e| e.object.is_none());
    if bare.len() > 1 {
        return bad("--material for every surface is given more than once".into());
    }
    if named.is_empty() {
        s.material = bare.pop().map(|e| e.material);
        return Ok(());
    }
    if let Some(b) = bare.first() {
        return bad(format!(
            "--material {} (every surface) with --material NAME=FILE (one object): give one or the other",
            b.material.origin.display()
        ));
    }
    let Baked::Cuts(cuts) = baked else {
        return bad("--material NAME=FILE edits a cuts bake (relight bake --method cuts)".into());
    };
    let scene = &mut cuts.scene;
    let mut seen = HashSet::new();
    for e in &named {
        let name = e.object.as_deref().unwrap_or_default();
        if !seen.insert(name) {
            return bad(format!("--material: object {name:?} is given twice"));
        }
        if !scene.objects.iter().any(|o| o.name == name) {
            let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
            return bad(format!(
                "--material: no object {name:?} in this bundle; its objects: {}",
                names.join(", ")
            ));
        }
    }
    let mut per_material: Vec<_> = (0..scene.materials.len())
        .map(|i| scene.maps.of(i as u32).cloned().map(Arc::new))
        .collect();
    for e in &named {
        let name = e.object.as_deref().unwrap_or_default();
        let m = e.material.desc.material;
        m.validate()
            .map_err(|err| MethodError::Settings(format!("material {m:?}: {err}")))?;
        let maps = load_override_maps(&e.material, s.material_allow_outside_paths)?;
        let id = scene.materials.len() as u32;
        scene.materials.push(m);
        per_material.push(maps.map(Arc::new));
        let Some(object) = scene.objects.iter().find(|o| o.name == name) else {
            continue;
        };
        let range = object.triangles.start as usize..object.triangles.end as usize;
        scene.mesh.material_ids[range]
            .iter_mut()
            .for_each(|i| *i = id);
    }
    scene.maps = SceneMaps::new(&scene.mesh, per_material)
        .map_err(|e| MethodError::Settings(format!("--material NAME=FILE: {e}")))?;
    Ok(())
}
