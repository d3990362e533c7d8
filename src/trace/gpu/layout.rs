//! The CPU tracer's acceleration structures and scene state as the flat buffers
//! `trace.wgsl` reads. Nothing is rebuilt: the GPU walks the very trees the CPU walks
//! (obvhs's CwBvh nodes are copied byte for byte), so that both find the same hits in
//! the same order.

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Mat4, Vec3};
use obvhs::{bvh2::Bvh2, rt_triangle::RtTriangle};

use super::super::{
    accel::{Analytic, GroupAccel, TriAttr},
    cones::RayCone,
    SceneState, TextureFilter, Tracer,
};
use crate::scene::Scene;

/// "No such thing" in an index field (the shader's `NONE`).
pub(super) const NONE: u32 = u32::MAX;
/// Marks an analytic primitive in a hit's primitive field (the shader's `ANALYTIC_BIT`).
pub(super) const ANALYTIC_BIT: u32 = super::super::ANALYTIC_BIT;
/// Words per CwBvh node (obvhs's `CwBvhNode` is 80 bytes).
const CW_WORDS: usize = 20;
/// Words per group record.
const GROUP_WORDS: usize = 8;
/// Vec4s per instance record (the shader's `inst_base`).
const INSTANCE_VEC4S: usize = 15;

const _: () = assert!(std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>() == CW_WORDS * 4);

type V4 = [f32; 4];

fn v4(v: Vec3, w: f32) -> V4 {
    [v.x, v.y, v.z, w]
}

/// The uniform of one dispatch (the shader's `Params`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(super) struct Params {
    pub eye: V4,
    pub corner: V4,
    pub du: V4,
    pub dv: V4,
    pub background: V4,
    pub ambient: V4,
    pub count: u32,
    pub max_depth: u32,
    pub ray_cones: u32,
    pub n_lights: u32,
    pub statics: StaticOffsets,
    pub state: StateOffsets,
    /// 1: primary hits only, no shading.
    pub primary_only: u32,
    /// 1: only each sample's colour and distance, 16 bytes instead of [`OUT_BYTES`].
    ///
    /// [`OUT_BYTES`]: super::OUT_BYTES
    pub colour_only: u32,
    pub pad: [u32; 2],
}

/// Where each part of the static buffers starts (vec4s of `data`, words of `words`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(super) struct StaticOffsets {
    tris_at: u32,
    attrs_at: u32,
    analytic_at: u32,
    b2_at: u32,
    materials_at: u32,
    n_materials: u32,
    texels_at: u32,
    levels_at: u32,
    textures_at: u32,
    groups_at: u32,
}

/// Where each part of one scene state's buffer starts (vec4s); `NONE`: absent.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(super) struct StateOffsets {
    inst_at: u32,
    top_at: u32,
    anim_nodes_at: u32,
    anim_tris_at: u32,
    anim_attr_at: u32,
    lights_at: u32,
}

/// What never changes for a tracer: every group's trees and primitives, materials,
/// textures.
pub(super) struct Statics {
    pub words: Vec<u32>,
    pub data: Vec<V4>,
    pub at: StaticOffsets,
    pub stacks: Stacks,
}

/// The traversal stack depths a tracer's trees need (the shader's `TRAVERSAL` and
/// `STACK2`). A traversal keeps at most one entry per level of the path it is on, so a
/// tree's depth is enough.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Stacks {
    /// The deepest CwBvh.
    pub cw: u32,
    /// The deepest Bvh2: the analytic sets', the morphing triangles' (refits keep the
    /// shape), and the top level's, which has one leaf per instance group at most and
    /// so is no deeper than their number.
    pub b2: u32,
}

impl Stacks {
    fn of(tracer: &Tracer) -> Self {
        let groups = std::iter::once(&tracer.static_geo)
            .chain(tracer.instance_groups.iter().map(|(_, g)| g));
        let mut s = Self { cw: 1, b2: 1 };
        for g in groups {
            if let Some(b) = g.cw_bvh() {
                s.cw = s.cw.max(cw_depth(&b.nodes, 0));
            }
            if let Some(b) = g.analytic_bvh() {
                s.b2 = s.b2.max(bvh2_depth(b));
            }
        }
        if let Some(b) = &tracer.anim_base {
            s.b2 = s.b2.max(bvh2_depth(b));
        }
        s.b2 = s.b2.max(tracer.instance_groups.len() as u32);
        s
    }
}

/// Levels of the CwBvh below and including node `i`.
fn cw_depth(nodes: &[obvhs::cwbvh::node::CwBvhNode], i: usize) -> u32 {
    let Some(n) = nodes.get(i) else {
        return 0;
    };
    // A node's inner children are stored together from `child_base_idx`.
    let first = n.child_base_idx as usize;
    let below = (first..first + n.imask.count_ones() as usize)
        .map(|c| cw_depth(nodes, c))
        .max()
        .unwrap_or(0);
    1 + below
}

/// Levels of a Bvh2 (its `max_depth` is a stack size, not the depth).
fn bvh2_depth(bvh: &Bvh2) -> u32 {
    let mut deepest = 0;
    let mut todo = vec![(0usize, 1u32)];
    while let Some((i, depth)) = todo.pop() {
        let Some(n) = bvh.nodes.get(i) else {
            continue;
        };
        deepest = deepest.max(depth);
        if !n.is_leaf() {
            let c = n.first_index as usize;
            todo.extend([(c, depth + 1), (c + 1, depth + 1)]);
        }
    }
    deepest
}

/// The flat parts of the static buffers, filled group by group.
#[derive(Default)]
struct Parts {
    nodes: Vec<u32>,
    groups: Vec<u32>,
    tris: Vec<V4>,
    attrs: Vec<V4>,
    analytic: Vec<V4>,
    b2: Vec<V4>,
}

fn push_tri(out: &mut Vec<V4>, t: &RtTriangle) {
    for v in [t.v0, t.e1, t.e2, t.ng] {
        out.push(v4(v.into(), 0.0));
    }
}

fn push_attr(out: &mut Vec<V4>, a: &TriAttr) {
    let [n0, n1, n2] = a.n;
    let [u0, u1, u2] = a.uv;
    out.push(v4(n0, u0.x));
    out.push(v4(n1, u0.y));
    out.push(v4(n2, u1.x));
    out.push([u1.y, u2.x, u2.y, f32::from_bits(a.material)]);
}

fn push_analytic(out: &mut Vec<V4>, a: &Analytic) {
    let (first, second, kind) = match a {
        Analytic::Sphere(s) => (v4(s.center, s.radius), [0.0; 4], 0u32),
        Analytic::Cone(c) => (v4(c.base, c.base_radius), v4(c.apex, c.apex_radius), 1),
    };
    out.extend([
        first,
        second,
        [f32::from_bits(kind), f32::from_bits(a.material()), 0.0, 0.0],
    ]);
}

/// A Bvh2's nodes, two vec4 each: (min, prim count), (max, first index); a leaf's
/// first index becomes `leaf(first)`.
fn push_bvh2(out: &mut Vec<V4>, bvh: &Bvh2, leaf: impl Fn(u32) -> u32) {
    for n in &bvh.nodes {
        let first = if n.is_leaf() {
            leaf(n.first_index)
        } else {
            n.first_index
        };
        out.push(v4(n.aabb.min.into(), f32::from_bits(n.prim_count)));
        out.push(v4(n.aabb.max.into(), f32::from_bits(first)));
    }
}

impl Parts {
    fn push_group(&mut self, g: &GroupAccel) {
        let node_base = (self.nodes.len() / CW_WORDS) as u32;
        let tri_base = (self.tris.len() / 4) as u32;
        let analytic_base = (self.analytic.len() / 3) as u32;
        if let Some(bvh) = g.cw_bvh() {
            self.nodes
                .extend_from_slice(bytemuck::cast_slice::<_, u32>(&bvh.nodes));
        }
        for (t, a) in g.tris.iter().zip(&g.attrs) {
            push_tri(&mut self.tris, t);
            push_attr(&mut self.attrs, a);
        }
        for a in &g.analytic {
            push_analytic(&mut self.analytic, a);
        }
        let abvh_base = match g.analytic_bvh() {
            Some(b) => {
                let base = (self.b2.len() / 2) as u32;
                push_bvh2(&mut self.b2, b, |i| i);
                base
            }
            None => NONE,
        };
        self.groups.extend([
            node_base,
            tri_base,
            analytic_base,
            g.analytic.len() as u32,
            abvh_base,
            g.cw_bvh().is_some() as u32,
            0,
            0,
        ]);
        debug_assert_eq!(self.groups.len() % GROUP_WORDS, 0);
    }
}

/// Materials (four vec4 each) and textures: per texture two words (first level,
/// levels), per level four (width, height, first texel), the texels themselves.
fn push_materials(scene: &Scene, data: &mut Vec<V4>, words: &mut Vec<u32>, at: &mut StaticOffsets) {
    at.materials_at = data.len() as u32;
    at.n_materials = scene.materials.len() as u32;
    for m in &scene.materials {
        let (tex, texels) = match m.texture.and_then(|t| scene.textures.get(t as usize)) {
            Some(t) => (m.texture.unwrap_or(NONE), (t.width * t.height) as f32),
            None => (NONE, 0.0),
        };
        data.extend([
            v4(m.ambient, m.shininess),
            v4(m.diffuse, m.transmission),
            v4(m.specular, m.effective_ior()),
            [f32::from_bits(tex), texels, 0.0, 0.0],
        ]);
    }
    at.texels_at = data.len() as u32;
    let mut levels = Vec::new();
    let mut textures = Vec::new();
    let mut texel = 0u32;
    for t in &scene.textures {
        textures.extend([(levels.len() / 4) as u32, t.levels() as u32]);
        for (w, h, texels) in (0..t.levels()).filter_map(|i| t.level(i)) {
            levels.extend([w, h, texel, 0]);
            data.extend(texels.iter().map(|c| v4(*c, 0.0)));
            texel += texels.len() as u32;
        }
    }
    at.textures_at = words.len() as u32;
    words.extend(textures);
    at.levels_at = words.len() as u32;
    words.extend(levels);
}

impl Statics {
    /// The static world (group 0) and each rigid instance group (1, 2, …).
    pub fn new(tracer: &Tracer) -> Self {
        let mut parts = Parts::default();
        parts.push_group(&tracer.static_geo);
        for (_, g) in &tracer.instance_groups {
            parts.push_group(g);
        }
        let mut at = StaticOffsets::default();
        let mut words = parts.nodes;
        at.groups_at = words.len() as u32;
        words.extend(parts.groups);
        let mut data = Vec::new();
        for (field, part) in [
            (&mut at.tris_at, parts.tris),
            (&mut at.attrs_at, parts.attrs),
            (&mut at.analytic_at, parts.analytic),
            (&mut at.b2_at, parts.b2),
        ] {
            *field = data.len() as u32;
            data.extend(part);
        }
        push_materials(&tracer.scene, &mut data, &mut words, &mut at);
        Self {
            words,
            data,
            at,
            stacks: Stacks::of(tracer),
        }
    }
}

fn mat3_cols(m: Mat3) -> [V4; 3] {
    [v4(m.x_axis, 0.0), v4(m.y_axis, 0.0), v4(m.z_axis, 0.0)]
}

fn mat4_cols(m: Mat4) -> [V4; 4] {
    [
        m.x_axis.into(),
        m.y_axis.into(),
        m.z_axis.into(),
        m.w_axis.into(),
    ]
}

/// One scene state (one 1 ms quantum): instances, the top level, the morphing
/// triangles refit at that time, lights.
pub(super) fn state(tracer: &Tracer, state: &SceneState) -> (Vec<V4>, StateOffsets) {
    let mut out: Vec<V4> = Vec::new();
    let mut at = StateOffsets {
        inst_at: 0,
        top_at: NONE,
        anim_nodes_at: NONE,
        anim_tris_at: NONE,
        anim_attr_at: NONE,
        lights_at: 0,
    };
    for inst in &state.instances {
        out.extend(mat4_cols(inst.inv));
        out.extend(mat3_cols(inst.normal));
        out.extend(mat3_cols(Mat3::from_mat4(inst.world)));
        let gpu_group = inst.group + 1; // group 0 is the static world
        let moving = inst.velocity != Mat4::ZERO;
        out.push([
            f32::from_bits(gpu_group),
            f32::from_bits(inst.group),
            f32::from_bits(moving as u32),
            0.0,
        ]);
        out.extend(mat4_cols(inst.velocity));
    }
    debug_assert_eq!(out.len(), state.instances.len() * INSTANCE_VEC4S);
    if let Some(top) = &state.top {
        at.top_at = out.len() as u32;
        // Leaves hold one instance each (`build_bvh2`): store the instance itself.
        push_bvh2(&mut out, top, |i| top.primitive_indices[i as usize]);
    }
    if let Some(anim) = &state.anim {
        at.anim_nodes_at = out.len() as u32;
        push_bvh2(&mut out, &anim.bvh, |i| i);
        at.anim_tris_at = out.len() as u32;
        for t in &anim.tris {
            push_tri(&mut out, t);
        }
        at.anim_attr_at = out.len() as u32;
        let scene = &tracer.scene;
        for (slot, (n, v)) in anim.normals.iter().zip(&anim.velocities).enumerate() {
            let src = anim.bvh.primitive_indices[slot] as usize;
            let m = scene.animated_triangles[src].material;
            let moving = *v != [Vec3::ZERO; 3];
            out.extend([v4(n[0], f32::from_bits(m)), v4(n[1], 0.0), v4(n[2], 0.0)]);
            out.extend([
                v4(v[0], f32::from_bits(moving as u32)),
                v4(v[1], 0.0),
                v4(v[2], 0.0),
            ]);
        }
    }
    at.lights_at = out.len() as u32;
    for (p, c) in &state.lights {
        out.extend([v4(*p, 0.0), v4(*c, 0.0)]);
    }
    (out, at)
}

/// The uniform of a dispatch of `count` samples in `state`.
pub(super) fn params(
    tracer: &Tracer,
    state: &SceneState,
    count: u32,
    statics: StaticOffsets,
    at: StateOffsets,
    mode: super::Mode,
) -> Params {
    let cam = &state.camera;
    let cones = tracer.options.texture_filter == TextureFilter::RayCones;
    let spread = if cones {
        RayCone::primary(cam).spread
    } else {
        0.0
    };
    Params {
        eye: v4(cam.eye, cam.hither),
        corner: v4(cam.corner, spread),
        du: v4(cam.du, tracer.scene_scale),
        dv: v4(cam.dv, 0.0),
        background: v4(tracer.scene.background, 0.0),
        ambient: v4(tracer.scene.ambient, 0.0),
        count,
        max_depth: tracer.options.max_depth,
        ray_cones: cones as u32,
        n_lights: state.lights.len() as u32,
        statics,
        state: at,
        primary_only: (mode == super::Mode::PrimaryHits) as u32,
        colour_only: (mode == super::Mode::Colours) as u32,
        pad: [0; 2],
    }
}

/// The Rust `Params` checked against `trace.wgsl`'s, without a GPU: a field reordered,
/// added or resized on one side only fails here, where the size alone would not see a
/// swap of two fields of one size.
#[cfg(test)]
mod tests {
    use super::*;

    /// `Params`' fields `$f…` (the offsets structs' inline, as the WGSL has them) as
    /// `(name, offset, size)` in bytes, named by their last part.
    macro_rules! params_fields {
        ($($($f:ident).+),* $(,)?) => {{
            fn size_of_field<F>(_: fn(&Params) -> &F) -> usize {
                std::mem::size_of::<F>()
            }
            vec![$((
                [$(stringify!($f)),+].last().unwrap().to_string(),
                std::mem::offset_of!(Params, $($f).+),
                size_of_field(|p: &Params| &p.$($f).+),
            )),*]
        }};
    }

    /// The WGSL struct `Params`' fields as `(name, offset, size)`, padding left out.
    fn wgsl_params() -> Vec<(String, usize, usize)> {
        let source =
            super::super::shader_source(crate::settings::MAX_DEPTH, Stacks { cw: 32, b2: 96 });
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
        let ty = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("Params"))
            .expect("a Params struct")
            .1;
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!("Params is not a struct");
        };
        members
            .iter()
            .map(|m| {
                let size = module.types[m.ty].inner.size(module.to_ctx()) as usize;
                (m.name.clone().unwrap_or_default(), m.offset as usize, size)
            })
            .filter(|(n, _, _)| !n.starts_with("pad"))
            .collect()
    }

    #[test]
    fn trace_wgsl_lays_out_params_as_the_rust_side() {
        let rust = params_fields!(
            eye,
            corner,
            du,
            dv,
            background,
            ambient,
            count,
            max_depth,
            ray_cones,
            n_lights,
            statics.tris_at,
            statics.attrs_at,
            statics.analytic_at,
            statics.b2_at,
            statics.materials_at,
            statics.n_materials,
            statics.texels_at,
            statics.levels_at,
            statics.textures_at,
            statics.groups_at,
            state.inst_at,
            state.top_at,
            state.anim_nodes_at,
            state.anim_tris_at,
            state.anim_attr_at,
            state.lights_at,
            primary_only,
            colour_only,
        );
        assert_eq!(
            rust,
            wgsl_params(),
            "struct Params: the Rust fields (left) are not the WGSL's (right), as (name, offset, size)"
        );
    }
}
