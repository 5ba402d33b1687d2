//! What a bundle says of its objects (`relight info`): per object of a baked scene, its
//! triangles, the distinct vertices they use and its materials with their parameters.

use crate::BakedScene;
use serde::Serialize;

/// One object of a baked scene, summarised.
#[derive(Clone, Debug, Serialize)]
pub struct ObjectSummary {
    /// The object's name.
    pub name: String,
    /// Its first triangle.
    pub first_triangle: u32,
    /// Its triangle count.
    pub triangles: u32,
    /// Distinct vertices its triangles use.
    pub vertices: usize,
    /// Its materials, by index.
    pub materials: Vec<MaterialSummary>,
}

/// A material of an object.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialSummary {
    /// Index into the scene's materials.
    pub index: u32,
    /// `Material::kind_name`.
    pub kind: &'static str,
    /// The material's parameters (its JSON without `type`).
    pub parameters: serde_json::Value,
    /// Whether the material has texture or normal maps.
    pub maps: bool,
}

impl MaterialSummary {
    /// `kind(key=value ...)` in one line, numbers as the `f32` they are, and " with maps".
    pub fn short(&self) -> String {
        fn value(v: &serde_json::Value) -> String {
            match v {
                serde_json::Value::Number(n) => {
                    n.as_f64().map_or(n.to_string(), |x| (x as f32).to_string())
                }
                serde_json::Value::Array(a) => {
                    format!("[{}]", a.iter().map(value).collect::<Vec<_>>().join(","))
                }
                other => other.to_string(),
            }
        }
        let params = self.parameters.as_object().map_or_else(String::new, |o| {
            o.iter()
                .map(|(k, x)| format!("{k}={}", value(x)))
                .collect::<Vec<_>>()
                .join(" ")
        });
        let maps = if self.maps { " with maps" } else { "" };
        format!("{}({params}){maps}", self.kind)
    }
}

impl BakedScene {
    /// Every object with its vertex count and materials, in triangle order.
    pub fn object_summaries(&self) -> Vec<ObjectSummary> {
        let mesh = &self.mesh;
        let distinct = |mut v: Vec<u32>| {
            v.sort_unstable();
            v.dedup();
            v
        };
        self.objects
            .iter()
            .map(|o| {
                let range = o.triangles.start as usize..o.triangles.end as usize;
                let verts = distinct(
                    mesh.indices[range.clone()]
                        .iter()
                        .flatten()
                        .copied()
                        .collect(),
                );
                let ids = distinct(mesh.material_ids[range].to_vec());
                let materials = ids
                    .into_iter()
                    .filter_map(|i| self.materials.get(i as usize).map(|m| (i, m)))
                    .map(|(index, m)| {
                        let mut parameters = serde_json::to_value(m).unwrap_or_default();
                        if let Some(obj) = parameters.as_object_mut() {
                            obj.remove("type");
                        }
                        MaterialSummary {
                            index,
                            kind: m.kind_name(),
                            parameters,
                            maps: self.maps.of(index).is_some(),
                        }
                    })
                    .collect();
                ObjectSummary {
                    name: o.name.clone(),
                    first_triangle: o.triangles.start,
                    triangles: o.triangles.len() as u32,
                    vertices: verts.len(),
                    materials,
                }
            })
            .collect()
    }
}
