//! Accessors: typed views of buffer data (vertex positions, normals, texture coordinates,
//! indices, animation keys). Strides, offsets, sparse substitutions and counts come from
//! the file, so each is checked against the bytes actually there before anything is read,
//! and integer components are normalised as the specification says.

use ::gltf::json;
use glam::{Vec2, Vec3};
use json::validation::Checked;

use super::container::Doc;
use crate::scene::SceneError;

/// Largest element count of an accessor without a buffer view (its data are zeros, so no
/// file size bounds it).
const MAX_ZERO_ELEMENTS: u64 = 1 << 24;

/// Decoded accessor contents: `count × comps` values, row by row.
struct Elements {
    values: Vec<f64>,
    comps: usize,
}

fn type_name(t: json::accessor::Type) -> &'static str {
    use json::accessor::Type::*;
    match t {
        Scalar => "SCALAR",
        Vec2 => "VEC2",
        Vec3 => "VEC3",
        Vec4 => "VEC4",
        Mat2 => "MAT2",
        Mat3 => "MAT3",
        Mat4 => "MAT4",
    }
}

fn component_size(c: json::accessor::ComponentType) -> usize {
    use json::accessor::ComponentType::*;
    match c {
        I8 | U8 => 1,
        I16 | U16 => 2,
        U32 | F32 => 4,
    }
}

/// One component, as stored (no normalisation). `b` holds exactly its bytes.
fn component(b: &[u8], c: json::accessor::ComponentType) -> f64 {
    use json::accessor::ComponentType::*;
    match c {
        I8 => b[0] as i8 as f64,
        U8 => b[0] as f64,
        I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
    }
}

/// The specification's normalised-integer decoding.
fn normalize(v: f64, c: json::accessor::ComponentType) -> f64 {
    use json::accessor::ComponentType::*;
    match c {
        I8 => (v / 127.0).max(-1.0),
        U8 => v / 255.0,
        I16 => (v / 32767.0).max(-1.0),
        U16 => v / 65535.0,
        U32 => v / 4_294_967_295.0,
        F32 => v,
    }
}

impl Doc {
    /// Decode an accessor of one of the `allowed` types, checking every range.
    fn read_accessor(
        &self,
        index: usize,
        ctx: &str,
        allowed: &[json::accessor::Type],
    ) -> Result<Elements, SceneError> {
        let ctx = format!("{ctx}: accessor {index}");
        let acc = self.root.accessors.get(index).ok_or_else(|| {
            self.invalid(format!(
                "{ctx} does not exist ({} defined)",
                self.root.accessors.len()
            ))
        })?;
        let Checked::Valid(json::accessor::GenericComponentType(ct)) = acc.component_type else {
            return Err(self.invalid(format!("{ctx} has an invalid componentType")));
        };
        let Checked::Valid(ty) = acc.type_ else {
            return Err(self.invalid(format!("{ctx} has an invalid type")));
        };
        if !allowed.contains(&ty) {
            let names: Vec<_> = allowed.iter().map(|t| type_name(*t)).collect();
            return Err(self.invalid(format!(
                "{ctx} is {}, expected {}",
                type_name(ty),
                names.join(" or ")
            )));
        }
        let comps = ty.multiplicity();
        let count = acc.count.0;
        let mut values = match acc.buffer_view {
            Some(view) => self.view_values(acc, view.value(), (ct, comps), &ctx)?,
            None => {
                if count > MAX_ZERO_ELEMENTS {
                    return Err(self.invalid(format!(
                        "{ctx} has {count} elements but no data (at most {MAX_ZERO_ELEMENTS} allowed)"
                    )));
                }
                vec![0.0; count as usize * comps]
            }
        };
        if let Some(sp) = &acc.sparse {
            self.apply_sparse(sp, &ctx, ct, comps, count, &mut values)?;
        }
        if acc.normalized {
            for v in &mut values {
                *v = normalize(*v, ct);
            }
        }
        Ok(Elements { values, comps })
    }

    /// The `comps` components of type `ct` of each of the elements of accessor `acc`,
    /// read from its bufferView `vi`.
    fn view_values(
        &self,
        acc: &json::Accessor,
        vi: usize,
        (ct, comps): (json::accessor::ComponentType, usize),
        ctx: &str,
    ) -> Result<Vec<f64>, SceneError> {
        let size = component_size(ct);
        let elem = (size * comps) as u64;
        let count = acc.count.0;
        let bytes = self.view_bytes(vi, ctx)?;
        let stride = match self.root.buffer_views.get(vi).and_then(|v| v.byte_stride) {
            Some(s) if (s.0 as u64) < elem => {
                return Err(self.invalid(format!(
                    "{ctx}: byteStride {} is smaller than an element ({elem} bytes)",
                    s.0
                )))
            }
            Some(s) => s.0 as u64,
            None => elem,
        };
        let off = acc.byte_offset.map_or(0, |o| o.0);
        if count > 0 {
            let need = (count - 1)
                .checked_mul(stride)
                .and_then(|x| x.checked_add(elem))
                .and_then(|x| x.checked_add(off));
            if need.is_none_or(|n| n > bytes.len() as u64) {
                return Err(self.invalid(format!(
                    "{ctx}: {count} elements at offset {off} (stride {stride}) do not fit in bufferView {vi} ({} bytes)",
                    bytes.len()
                )));
            }
        }
        let mut values = Vec::with_capacity(count as usize * comps);
        for i in 0..count as usize {
            let start = off as usize + i * stride as usize;
            for c in 0..comps {
                let at = start + c * size;
                values.push(component(&bytes[at..at + size], ct));
            }
        }
        Ok(values)
    }

    fn apply_sparse(
        &self,
        sp: &json::accessor::sparse::Sparse,
        ctx: &str,
        ct: json::accessor::ComponentType,
        comps: usize,
        count: u64,
        values: &mut [f64],
    ) -> Result<(), SceneError> {
        let n = sp.count.0;
        if n > count {
            return Err(self.invalid(format!(
                "{ctx}: sparse count {n} exceeds the accessor's count {count}"
            )));
        }
        let Checked::Valid(json::accessor::IndexComponentType(ict)) = sp.indices.component_type
        else {
            return Err(self.invalid(format!(
                "{ctx}: sparse indices have an invalid componentType"
            )));
        };
        let isize_ = component_size(ict) as u64;
        let ibytes = self.view_bytes(sp.indices.buffer_view.value(), ctx)?;
        let ioff = sp.indices.byte_offset.0;
        let vsize = (component_size(ct) * comps) as u64;
        let vbytes = self.view_bytes(sp.values.buffer_view.value(), ctx)?;
        let voff = sp.values.byte_offset.0;
        let fits = |off: u64, each: u64, len: usize| {
            n.checked_mul(each)
                .and_then(|x| x.checked_add(off))
                .is_some_and(|e| e <= len as u64)
        };
        if !fits(ioff, isize_, ibytes.len()) || !fits(voff, vsize, vbytes.len()) {
            return Err(self.invalid(format!(
                "{ctx}: sparse indices or values do not fit in their buffer views"
            )));
        }
        let csize = component_size(ct);
        for k in 0..n as usize {
            let at = ioff as usize + k * isize_ as usize;
            let target = component(&ibytes[at..at + isize_ as usize], ict);
            if target >= count as f64 {
                return Err(self.invalid(format!(
                    "{ctx}: sparse index {target} is out of range (count {count})"
                )));
            }
            let target = target as usize;
            for c in 0..comps {
                let at = voff as usize + k * vsize as usize + c * csize;
                values[target * comps + c] = component(&vbytes[at..at + csize], ct);
            }
        }
        Ok(())
    }

    /// An accessor read as finite `f32` values.
    pub(super) fn floats(
        &self,
        index: usize,
        ctx: &str,
        allowed: &[json::accessor::Type],
    ) -> Result<(Vec<f32>, usize), SceneError> {
        let e = self.read_accessor(index, ctx, allowed)?;
        let mut out = Vec::with_capacity(e.values.len());
        for (i, &v) in e.values.iter().enumerate() {
            let f = v as f32;
            if !f.is_finite() {
                return Err(self.invalid(format!(
                    "{ctx}: accessor {index} element {} is not finite",
                    i / e.comps.max(1)
                )));
            }
            out.push(f);
        }
        Ok((out, e.comps))
    }

    pub(super) fn vec3s(&self, index: usize, ctx: &str) -> Result<Vec<Vec3>, SceneError> {
        let (f, _) = self.floats(index, ctx, &[json::accessor::Type::Vec3])?;
        Ok(f.chunks_exact(3).map(Vec3::from_slice).collect())
    }

    /// Texture coordinates, flipped to this renderer's `v` (up).
    pub(super) fn texcoords(&self, index: usize, ctx: &str) -> Result<Vec<Vec2>, SceneError> {
        let (f, _) = self.floats(index, ctx, &[json::accessor::Type::Vec2])?;
        Ok(f.chunks_exact(2)
            .map(|c| Vec2::new(c[0], 1.0 - c[1]))
            .collect())
    }

    /// Vertex indices, each checked against the vertex count.
    pub(super) fn indices(
        &self,
        index: usize,
        ctx: &str,
        vertices: usize,
    ) -> Result<Vec<u32>, SceneError> {
        use json::accessor::ComponentType::*;
        let acc_ct = self.root.accessors.get(index).map(|a| a.component_type);
        if let Some(Checked::Valid(json::accessor::GenericComponentType(ct))) = acc_ct {
            if !matches!(ct, U8 | U16 | U32) || self.root.accessors[index].normalized {
                return Err(self.invalid(format!(
                    "{ctx}: index accessor {index} must hold unsigned, unnormalised integers"
                )));
            }
        }
        let e = self.read_accessor(index, ctx, &[json::accessor::Type::Scalar])?;
        let mut out = Vec::with_capacity(e.values.len());
        for (i, &v) in e.values.iter().enumerate() {
            if v >= vertices as f64 {
                return Err(self.invalid(format!(
                    "{ctx}: index {i} of accessor {index} is {v}, out of range for {vertices} vertices"
                )));
            }
            out.push(v as u32);
        }
        Ok(out)
    }
}
