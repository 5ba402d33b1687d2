//! Accessor data of the glTF reader: bounds checked against the buffer view and buffer
//! before any element is read, integers normalised as glTF says (`max(c / (2^(n-1) - 1), -1)`
//! signed, `c / (2^n - 1)` unsigned), non-finite values refused.

use super::Reader;
use crate::error::SceneError;
use gltf::accessor::{DataType, Dimensions};

impl Reader<'_> {
    /// Bytes of accessor `a` from its first element: (data, element stride, component count).
    pub(super) fn view(&self, acc: &gltf::Accessor) -> Result<(&[u8], usize, usize), SceneError> {
        let a = acc.index();
        if acc.sparse().is_some() {
            return Err(SceneError::unsupported(
                self.path,
                format!("accessor {a} is sparse"),
            ));
        }
        let comps = match acc.dimensions() {
            Dimensions::Scalar => 1,
            Dimensions::Vec2 => 2,
            Dimensions::Vec3 => 3,
            Dimensions::Vec4 => 4,
            t => return Err(self.err(format!("accessor {a}: unexpected type {t:?}"))),
        };
        let csize = acc.data_type().size();
        let view = acc.view().ok_or_else(|| {
            SceneError::unsupported(self.path, format!("accessor {a} without bufferView"))
        })?;
        let bv = view.index();
        let buf = self.buffers.get(view.buffer().index()).ok_or_else(|| {
            self.err(format!(
                "bufferView {bv}: buffer {} does not exist",
                view.buffer().index()
            ))
        })?;
        let elem = comps * csize;
        let stride = view.stride().unwrap_or(elem);
        let view_end = view
            .offset()
            .checked_add(view.length())
            .filter(|&e| e <= buf.len());
        // Bytes of the view the accessor spans: offset + (count - 1) stride + element size.
        let need = match acc.count().checked_sub(1) {
            None => Some(acc.offset()),
            Some(c) => c
                .checked_mul(stride)
                .and_then(|v| v.checked_add(elem))
                .and_then(|v| v.checked_add(acc.offset())),
        };
        match (view_end, need) {
            (Some(_), Some(need)) if stride >= elem && need <= view.length() => {
                let data = &buf[view.offset() + acc.offset()..view.offset() + need];
                Ok((data, stride, comps))
            }
            _ => Err(SceneError::TooLarge {
                at: crate::error::Location::file(self.path),
                msg: format!(
                    "accessor {a} ({} x {:?} {:?}) lies beyond its buffer view or buffer",
                    acc.count(),
                    acc.dimensions(),
                    acc.data_type()
                ),
            }),
        }
    }

    fn component(data: &[u8], ct: DataType, normalized: bool) -> f32 {
        let b = |n: usize| data[n];
        match ct {
            DataType::I8 => {
                let v = b(0) as i8 as f32;
                if normalized {
                    (v / 127.0).max(-1.0)
                } else {
                    v
                }
            }
            DataType::U8 => {
                let v = b(0) as f32;
                if normalized {
                    v / 255.0
                } else {
                    v
                }
            }
            DataType::I16 => {
                let v = i16::from_le_bytes([b(0), b(1)]) as f32;
                if normalized {
                    (v / 32767.0).max(-1.0)
                } else {
                    v
                }
            }
            DataType::U16 => {
                let v = u16::from_le_bytes([b(0), b(1)]) as f32;
                if normalized {
                    v / 65535.0
                } else {
                    v
                }
            }
            DataType::U32 => u32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f32,
            _ => f32::from_le_bytes([b(0), b(1), b(2), b(3)]),
        }
    }

    pub(super) fn floats<const N: usize>(
        &self,
        acc: &gltf::Accessor,
    ) -> Result<Vec<[f32; N]>, SceneError> {
        let a = acc.index();
        let (data, stride, comps) = self.view(acc)?;
        if comps != N {
            return Err(self.err(format!(
                "accessor {a}: expected {N} components, found {:?}",
                acc.dimensions()
            )));
        }
        let (ct, csize, normalized) = (acc.data_type(), acc.data_type().size(), acc.normalized());
        let mut out = Vec::with_capacity(acc.count());
        for e in 0..acc.count() {
            let v: [f32; N] = std::array::from_fn(|c| {
                Self::component(&data[e * stride + c * csize..], ct, normalized)
            });
            if v.iter().any(|x| !x.is_finite()) {
                return Err(self.err(format!("accessor {a}: element {e} is not finite")));
            }
            out.push(v);
        }
        Ok(out)
    }

    pub(super) fn indices(&self, acc: &gltf::Accessor) -> Result<Vec<u32>, SceneError> {
        let (data, stride, comps) = self.view(acc)?;
        let size = match (acc.data_type(), comps) {
            (DataType::U8, 1) => 1,
            (DataType::U16, 1) => 2,
            (DataType::U32, 1) => 4,
            _ => {
                return Err(self.err(format!(
                    "accessor {}: indices must be unsigned scalars",
                    acc.index()
                )))
            }
        };
        Ok((0..acc.count())
            .map(|e| {
                let d = &data[e * stride..e * stride + size];
                match size {
                    1 => d[0] as u32,
                    2 => u16::from_le_bytes([d[0], d[1]]) as u32,
                    _ => u32::from_le_bytes([d[0], d[1], d[2], d[3]]),
                }
            })
            .collect())
    }
}
