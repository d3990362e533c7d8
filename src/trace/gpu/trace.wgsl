// The GPU tracer (`trace/gpu/mod.rs`): one invocation traces one sample, the CPU
// tracer's `Tracer::sample` step for step, over the same acceleration structures
// (uploaded by `layout.rs`): the static world's and each rigid group's obvhs CwBvh and
// analytic Bvh2, the top level over the instances and the refit Bvh2 of the morphing
// triangles at the batch's time. Traversal orders are obvhs's, so that of two hits at
// the same distance the same one wins. Prepended by the Rust side: STACK, TRAVERSAL,
// STACK2, NONE, FAR, ANALYTIC_BIT, NODE_EPSILON, MIN_COS.

struct Params {
    eye: vec4<f32>,        // w: hither
    corner: vec4<f32>,     // w: the primary ray cone's spread
    du: vec4<f32>,         // w: scene scale (for secondary-ray offsets)
    dv: vec4<f32>,
    background: vec4<f32>,
    ambient: vec4<f32>,
    count: u32,
    max_depth: u32,
    ray_cones: u32,
    n_lights: u32,
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
    inst_at: u32,
    top_at: u32,
    anim_nodes_at: u32,
    anim_tris_at: u32,
    anim_attr_at: u32,
    lights_at: u32,
    // 1: primary hits only, no shading (the benchmark's primary rays).
    primary_only: u32,
    // 1: only (colour, t) per sample, one vec4 each (the ideal images' read-back).
    colour_only: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
// CwBvh nodes (20 words each), group records (8 words), texture records (2 words)
// and texture levels (4 words).
@group(0) @binding(1) var<storage, read> words: array<u32>;
// Triangles, their attributes, analytic shapes, analytic Bvh2 nodes, materials, texels.
@group(0) @binding(2) var<storage, read> data: array<vec4<f32>>;
// The batch's scene state: instances, top-level and morphing Bvh2 nodes, morphing
// triangles and their attributes, lights.
@group(0) @binding(3) var<storage, read> dyn_: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> points: array<vec2<f32>>;
// Per sample OUT_VEC4S vec4: (colour, t), (hit kind, instance group, primitive,
// secondary rays traced | DYNAMIC_BIT), (hit point, 0), (velocity, 0), (anchor, 0).
@group(0) @binding(5) var<storage, read_write> out: array<vec4<u32>>;

const OUT_VEC4S: u32 = 5u;
const DYNAMIC_BIT: u32 = 0x80000000u;

// Whether something moving took part in this invocation's sample (`Sample::dynamic`):
// set wherever the CPU tracer sets it, deep in traversal and shading, so a private
// flag rather than a value threaded through every call.
var<private> g_dynamic: bool;

// vec4s per morphing triangle's attributes: normals (the first's w: material),
// vertex velocities (the first's w: 1 where any is not zero).
const ANIM_VEC4S: u32 = 6u;

struct Ray {
    o: vec3<f32>,
    d: vec3<f32>,
    inv: vec3<f32>,
    tmin: f32,
    tmax: f32,
}

// Hit kinds, as `HitId` names them.
const MISS: u32 = 0u;
const STATIC: u32 = 1u;
const INSTANCE: u32 = 2u;
const ANIM: u32 = 3u;

struct Hit {
    t: f32,
    kind: u32,
    inst: u32,   // index into the state's instances (INSTANCE)
    prim: u32,   // triangle slot, or ANALYTIC_BIT | analytic slot
}

fn no_hit() -> Hit {
    return Hit(FAR, MISS, 0u, 0u);
}

// obvhs's `safe_inverse`: tiny components become ±1/EPSILON (by the sign bit).
fn safe_inverse(x: f32) -> f32 {
    let eps = 1.1920929e-7;
    if abs(x) <= eps {
        return select(1.0, -1.0, (bitcast<u32>(x) >> 31u) == 1u) / eps;
    }
    return 1.0 / x;
}

fn make_ray(o: vec3<f32>, d: vec3<f32>, tmin: f32, tmax: f32) -> Ray {
    return Ray(o, d, vec3<f32>(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z)), tmin, tmax);
}

// glam's `normalize`: times the reciprocal of the length.
fn normalize_cpu(v: vec3<f32>) -> vec3<f32> {
    return v * (1.0 / sqrt(dot(v, v)));
}

// glam's `normalize_or`.
fn normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let len = sqrt(dot(v, v));
    if len > 0.0 && len < FAR {
        return v * (1.0 / len);
    }
    return fallback;
}

fn max3(v: vec3<f32>) -> f32 {
    return max(max(v.x, v.y), v.z);
}

fn min3(v: vec3<f32>) -> f32 {
    return min(min(v.x, v.y), v.z);
}

// ---- Triangles (obvhs RtTriangle: v0, e1 = v0 - v1, e2 = v2 - v0, ng = e1 × e2) ----

// RtTriangle::intersect on the four vec4 at `k` of `src` (data, or dyn_ if `in_dyn`).
fn tri_at(in_dyn: bool, k: u32, i: u32) -> vec3<f32> {
    if in_dyn {
        return dyn_[k + i].xyz;
    }
    return data[k + i].xyz;
}

fn tri_intersect(in_dyn: bool, k: u32, r: Ray) -> f32 {
    let v0 = tri_at(in_dyn, k, 0u);
    let e1 = tri_at(in_dyn, k, 1u);
    let e2 = tri_at(in_dyn, k, 2u);
    let ng = tri_at(in_dyn, k, 3u);
    let c = v0 - r.o;
    let rr = cross(r.d, c);
    let inv_det = 1.0 / dot(ng, r.d);
    let u = dot(rr, e2) * inv_det;
    let v = dot(rr, e1) * inv_det;
    let w = 1.0 - u - v;
    let bits = bitcast<u32>(u) | bitcast<u32>(v) | bitcast<u32>(w);
    if inv_det != 0.0 && (bits & 0x80000000u) == 0u {
        let t = dot(ng, c) * inv_det;
        if t >= r.tmin && t <= r.tmax {
            return t;
        }
    }
    return FAR;
}

fn tri_barycentric(in_dyn: bool, k: u32, r: Ray) -> vec2<f32> {
    let v0 = tri_at(in_dyn, k, 0u);
    let rr = cross(r.d, v0 - r.o);
    return vec2<f32>(dot(rr, tri_at(in_dyn, k, 2u)), dot(rr, tri_at(in_dyn, k, 1u))) / dot(tri_at(in_dyn, k, 3u), r.d);
}

// ---- Analytic shapes (intersect.rs) ----

fn sphere_intersect(center: vec3<f32>, radius: f32, r: Ray) -> f32 {
    let rad = abs(radius);
    let oc = r.o - center;
    let a = dot(r.d, r.d);
    let half_b = dot(oc, r.d);
    let cc = dot(oc, oc) - rad * rad;
    let disc = half_b * half_b - a * cc;
    if disc < 0.0 || a == 0.0 {
        return FAR;
    }
    let sq = sqrt(disc);
    let t0 = (-half_b - sq) / a;
    if t0 >= r.tmin && t0 <= r.tmax {
        return t0;
    }
    let t1 = (-half_b + sq) / a;
    if t1 >= r.tmin && t1 <= r.tmax {
        return t1;
    }
    return FAR;
}

fn cone_root_ok(t: f32, r: Ray, ow: f32, dw: f32, h: f32, r0: f32, k: f32) -> bool {
    if t >= r.tmin && t <= r.tmax {
        let s = ow + t * dw;
        return s >= 0.0 && s <= h && r0 + k * s >= 0.0;
    }
    return false;
}

fn cone_intersect(base: vec3<f32>, base_radius: f32, apex: vec3<f32>, apex_radius: f32, r: Ray) -> f32 {
    let axis_full = apex - base;
    let h = sqrt(dot(axis_full, axis_full));
    if h == 0.0 {
        return FAR;
    }
    let w = axis_full / h;
    let r0 = abs(base_radius);
    let r1 = abs(apex_radius);
    let k = (r1 - r0) / h;
    let o = r.o - base;
    let d = r.d;
    let od = dot(o, d);
    let dd = dot(d, d);
    let ow = dot(o, w);
    let dw = dot(d, w);
    let oo = dot(o, o);
    let a = dd - dw * dw - k * k * dw * dw;
    let b = 2.0 * (od - ow * dw - k * dw * (r0 + k * ow));
    let cc = oo - ow * ow - (r0 + k * ow) * (r0 + k * ow);
    var t0: f32;
    var t1: f32;
    if abs(a) < 1e-12 {
        if abs(b) < 1e-12 {
            return FAR;
        }
        t0 = -cc / b;
        t1 = FAR;
    } else {
        let disc = b * b - 4.0 * a * cc;
        if disc < 0.0 {
            return FAR;
        }
        let sq = sqrt(disc);
        let x0 = (-b - sq) / (2.0 * a);
        let x1 = (-b + sq) / (2.0 * a);
        t0 = min(x0, x1);
        t1 = max(x0, x1);
    }
    if cone_root_ok(t0, r, ow, dw, h, r0, k) {
        return t0;
    }
    if t1 < FAR && cone_root_ok(t1, r, ow, dw, h, r0, k) {
        return t1;
    }
    return FAR;
}

// Analytic shape `i` (absolute slot): (a, b, kind/material) vec4s.
fn analytic_intersect(i: u32, r: Ray) -> f32 {
    let k = P.analytic_at + 3u * i;
    let a = data[k];
    let b = data[k + 1u];
    if bitcast<u32>(data[k + 2u].x) == 0u {
        return sphere_intersect(a.xyz, a.w, r);
    }
    return cone_intersect(a.xyz, a.w, b.xyz, b.w, r);
}

fn analytic_material(i: u32) -> u32 {
    return bitcast<u32>(data[P.analytic_at + 3u * i + 2u].y);
}

fn analytic_normal(i: u32, p: vec3<f32>) -> vec3<f32> {
    let k = P.analytic_at + 3u * i;
    let a = data[k];
    let b = data[k + 1u];
    if bitcast<u32>(data[k + 2u].x) == 0u {
        return normalize_or(p - a.xyz, vec3<f32>(0.0, 1.0, 0.0));
    }
    let axis = b.xyz - a.xyz;
    let h = max(sqrt(dot(axis, axis)), 1e-20);
    let w = axis / h;
    let kk = (abs(b.w) - abs(a.w)) / h;
    let q = p - a.xyz;
    let s = dot(q, w);
    let radial = normalize_or(q - w * s, any_orthonormal(w));
    return normalize_or(radial - w * kk, radial);
}

// glam's `any_orthonormal_vector`.
fn any_orthonormal(v: vec3<f32>) -> vec3<f32> {
    let sign = select(1.0, -1.0, (bitcast<u32>(v.z) >> 31u) == 1u);
    let a = -1.0 / (sign + v.z);
    let b = v.x * v.y * a;
    return vec3<f32>(b, sign + v.y * v.y * a, -v.y);
}

// ---- Materials ----

fn material_transmission(m: u32) -> f32 {
    if m >= P.n_materials {
        return 0.0;
    }
    return data[P.materials_at + 4u * m + 1u].w;
}

// ---- Groups ----

struct Group {
    node_base: u32,     // first CwBvh node (words / 20)
    tri_base: u32,      // first triangle slot
    analytic_base: u32, // first analytic slot
    analytic_count: u32,
    abvh_base: u32,     // first analytic Bvh2 node, NONE when tested one by one
    has_cw: u32,
}

fn group(g: u32) -> Group {
    let k = P.groups_at + 8u * g;
    return Group(words[k], words[k + 1u], words[k + 2u], words[k + 3u], words[k + 4u], words[k + 5u]);
}

// ---- CwBvh (obvhs cwbvh: traverse! and CwBvhNode::intersect_ray) ----

fn octant_inv4(d: vec3<f32>) -> u32 {
    return select(0x04040404u, 0u, d.x < 0.0) | select(0x02020202u, 0u, d.y < 0.0) | select(0x01010101u, 0u, d.z < 0.0);
}

fn byte_of(w: u32, i: u32) -> u32 {
    return (w >> (8u * i)) & 0xffu;
}

// The byte `child` of the eight-byte field at word `k` (two words, little-endian).
fn byte8(k: u32, child: u32) -> f32 {
    return f32(byte_of(words[k + child / 4u], child % 4u));
}

// CwBvhNode::intersect_ray: the node's hit mask (child bits at their traversal slots).
fn cw_node_hits(k: u32, r: Ray, oct_inv4: u32) -> u32 {
    let p = vec3<f32>(bitcast<f32>(words[k]), bitcast<f32>(words[k + 1u]), bitcast<f32>(words[k + 2u]));
    let e = words[k + 3u];
    let ext = vec3<f32>(bitcast<f32>(byte_of(e, 0u) << 23u), bitcast<f32>(byte_of(e, 1u) << 23u), bitcast<f32>(byte_of(e, 2u) << 23u));
    let adj_inv = ext * r.inv;
    let adj_o = (p - r.o) * r.inv;
    var hit_mask = 0u;
    for (var half = 0u; half < 2u; half++) {
        let meta4 = words[k + 6u + half];
        let is_inner = (meta4 & (meta4 << 1u)) & 0x10101010u;
        let inner_mask = (is_inner >> 4u) * 0xffu;
        let bit_index4 = (meta4 ^ (oct_inv4 & inner_mask)) & 0x1f1f1f1fu;
        let child_bits4 = (meta4 >> 5u) & 0x07070707u;
        for (var j = 0u; j < 4u; j++) {
            let child = 4u * half + j;
            let lo = vec3<f32>(byte8(k + 8u, child), byte8(k + 12u, child), byte8(k + 16u, child));
            let hi = vec3<f32>(byte8(k + 10u, child), byte8(k + 14u, child), byte8(k + 18u, child));
            let neg = r.d < vec3<f32>(0.0);
            let qmin = select(lo, hi, neg);
            let qmax = select(hi, lo, neg);
            let tmin3 = qmin * adj_inv + adj_o;
            let tmax3 = qmax * adj_inv + adj_o;
            let tmin = max(max3(tmin3), NODE_EPSILON);
            let tmax = min(min3(tmax3), r.tmax);
            if tmin <= tmax {
                hit_mask |= byte_of(child_bits4, j) << byte_of(bit_index4, j);
            }
        }
    }
    return hit_mask;
}

// A group's triangles: `shadow` false: the closest hit (slot in `best_prim`, returns t);
// `shadow` true: whether an opaque triangle blocks, multiplying `acc` by transmissive
// ones' transmission (returns 0 when blocked, FAR otherwise).
fn cw_traverse(gr: Group, r_in: Ray, shadow: bool, acc: ptr<function, f32>, best_prim: ptr<function, u32>) -> f32 {
    var r = r_in;
    let oct_inv4 = octant_inv4(r.d);
    var stack: array<vec2<u32>, TRAVERSAL>;
    var sp = 0u;
    var current = vec2<u32>(0u, 0x80000000u);
    var prims = vec2<u32>(0u, 0u);
    var best = FAR;
    loop {
        while prims.y != 0u {
            let local = firstLeadingBit(prims.y);
            prims.y &= ~(1u << local);
            let slot = prims.x + local;
            let tk = P.tris_at + 4u * (gr.tri_base + slot);
            var t = tri_intersect(false, tk, r);
            if shadow && t < FAR {
                let m = bitcast<u32>(data[P.attrs_at + 4u * (gr.tri_base + slot) + 3u].w);
                let tr = material_transmission(m);
                if tr > 0.0 {
                    *acc *= tr;
                    t = FAR;
                }
            }
            if t < r.tmax {
                if shadow {
                    return 0.0;
                }
                best = t;
                *best_prim = slot;
                r.tmax = t;
            }
        }
        prims = vec2<u32>(0u, 0u);
        if (current.y & 0xff000000u) != 0u {
            let hits_imask = current.y;
            let offset = firstLeadingBit(hits_imask);
            let base = current.x;
            current.y &= ~(1u << offset);
            if (current.y & 0xff000000u) != 0u && sp < TRAVERSAL {
                stack[sp] = current;
                sp++;
            }
            let slot_index = (offset - 24u) ^ (oct_inv4 & 0xffu);
            let relative = countOneBits(hits_imask & ~(0xffffffffu << slot_index));
            let nk = 20u * (gr.node_base + base + relative);
            let hitmask = cw_node_hits(nk, r, oct_inv4);
            current.x = words[nk + 4u];
            prims.x = words[nk + 5u];
            current.y = (hitmask & 0xff000000u) | ((words[nk + 3u] >> 24u) & 0xffu);
            prims.y = hitmask & 0x00ffffffu;
        } else {
            current = vec2<u32>(0u, 0u);
        }
        if prims.y == 0u && (current.y & 0xff000000u) == 0u {
            if sp == 0u {
                break;
            }
            sp--;
            current = stack[sp];
        }
    }
    return best;
}

// ---- Bvh2 (obvhs Bvh2::ray_traverse_dynamic) ----

// Aabb::intersect_ray: the entry distance, FAR on a miss.
fn box_intersect(lo: vec3<f32>, hi: vec3<f32>, r: Ray) -> f32 {
    let t1 = (lo - r.o) * r.inv;
    let t2 = (hi - r.o) * r.inv;
    let tmin = max3(min(t1, t2));
    let tmax = min3(max(t1, t2));
    if tmax >= tmin && tmax >= 0.0 {
        return tmin;
    }
    return FAR;
}

// Bvh2 node `i` of the tree at vec4 `at`: (min, prim count), (max, first index).
fn b2_lo(in_dyn: bool, at: u32, i: u32) -> vec4<f32> {
    if in_dyn {
        return dyn_[at + 2u * i];
    }
    return data[at + 2u * i];
}

fn b2_hi(in_dyn: bool, at: u32, i: u32) -> vec4<f32> {
    if in_dyn {
        return dyn_[at + 2u * i + 1u];
    }
    return data[at + 2u * i + 1u];
}

// Leaf tests of the inner Bvh2s: an analytic set (`anim` false: slots from
// `prim_base`) or the morphing triangles (`anim` true). Same contract as cw_traverse.
fn leaf_test(anim: bool, prim_base: u32, slot: u32, r: Ray, shadow: bool, acc: ptr<function, f32>) -> f32 {
    if anim {
        var t = tri_intersect(true, P.anim_tris_at + 4u * slot, r);
        if shadow && t < FAR {
            // Tracer::shadow: any moving triangle the shadow ray meets makes it dynamic.
            if bitcast<u32>(dyn_[P.anim_attr_at + ANIM_VEC4S * slot + 3u].w) != 0u {
                g_dynamic = true;
            }
            let tr = material_transmission(bitcast<u32>(dyn_[P.anim_attr_at + ANIM_VEC4S * slot].w));
            if tr > 0.0 {
                *acc *= tr;
                t = FAR;
            }
        }
        return t;
    }
    let t = analytic_intersect(prim_base + slot, r);
    if shadow {
        if t < FAR {
            let tr = material_transmission(analytic_material(prim_base + slot));
            if tr > 0.0 {
                *acc *= tr;
                return FAR;
            }
            return 0.0;
        }
        return FAR;
    }
    return t;
}

// Leaf `node` of an inner Bvh2: updates `r.tmax` and `best`; false: stop (blocked).
fn b2_leaf(anim: bool, prim_base: u32, lo: vec4<f32>, hi: vec4<f32>, r: ptr<function, Ray>, shadow: bool, acc: ptr<function, f32>, best: ptr<function, u32>) -> bool {
    let first = bitcast<u32>(hi.w);
    let count = bitcast<u32>(lo.w);
    for (var s = first; s < first + count; s++) {
        let t = leaf_test(anim, prim_base, s, *r, shadow, acc);
        if t < (*r).tmax {
            if shadow {
                return false;
            }
            *best = s;
            (*r).tmax = t;
        }
    }
    return true;
}

// The next node of a Bvh2 walk after visiting both children of one: the nearer
// hit child (`left` first when both are, `right` pushed), else the top of the stack;
// false when the walk is done.
fn b2_next(go_left: bool, go_right: bool, left: u32, right: u32,
           stack: ptr<function, array<u32, STACK2>>, sp: ptr<function, u32>,
           current: ptr<function, u32>) -> bool {
    if go_left && go_right {
        *current = left;
        if *sp < STACK2 {
            (*stack)[*sp] = right;
            *sp = *sp + 1u;
        }
    } else if go_left {
        *current = left;
    } else if go_right {
        *current = right;
    } else {
        if *sp == 0u {
            return false;
        }
        *sp = *sp - 1u;
        *current = (*stack)[*sp];
    }
    return true;
}

// An inner Bvh2 at vec4 `at` (of dyn_ if `anim`): the closest hit's t (slot in
// `best`), or for `shadow` 0 when blocked. Returns FAR when nothing was hit.
fn b2_traverse(anim: bool, at: u32, prim_base: u32, r_in: Ray, shadow: bool, acc: ptr<function, f32>, best: ptr<function, u32>) -> f32 {
    var r = r_in;
    let tmax0 = r.tmax;
    let root_lo = b2_lo(anim, at, 0u);
    let root_hi = b2_hi(anim, at, 0u);
    if !(box_intersect(root_lo.xyz, root_hi.xyz, r) < r.tmax) {
        return FAR;
    }
    if bitcast<u32>(root_lo.w) != 0u {
        if !b2_leaf(anim, prim_base, root_lo, root_hi, &r, shadow, acc, best) {
            return 0.0;
        }
        return select(FAR, r.tmax, r.tmax < tmax0);
    }
    var stack: array<u32, STACK2>;
    var sp = 0u;
    var current = bitcast<u32>(root_hi.w);
    loop {
        var l_lo = b2_lo(anim, at, current);
        var l_hi = b2_hi(anim, at, current);
        var r_lo = b2_lo(anim, at, current + 1u);
        var r_hi = b2_hi(anim, at, current + 1u);
        var lt = box_intersect(l_lo.xyz, l_hi.xyz, r);
        var rt = box_intersect(r_lo.xyz, r_hi.xyz, r);
        if lt > rt {
            let a = l_lo; l_lo = r_lo; r_lo = a;
            let b = l_hi; l_hi = r_hi; r_hi = b;
            let c = lt; lt = rt; rt = c;
        }
        var go_left = lt < r.tmax;
        if go_left && bitcast<u32>(l_lo.w) != 0u {
            if !b2_leaf(anim, prim_base, l_lo, l_hi, &r, shadow, acc, best) {
                return 0.0;
            }
            go_left = false;
        }
        var go_right = rt < r.tmax;
        if go_right && bitcast<u32>(r_lo.w) != 0u {
            if !b2_leaf(anim, prim_base, r_lo, r_hi, &r, shadow, acc, best) {
                return 0.0;
            }
            go_right = false;
        }
        if !b2_next(go_left, go_right, bitcast<u32>(l_hi.w), bitcast<u32>(r_hi.w), &stack, &sp, &current) {
            break;
        }
    }
    return select(FAR, r.tmax, r.tmax < tmax0);
}

// ---- A group (GroupAccel::closest / occlusion) ----

// The closest hit in group `g` along `r` (t, and the primitive in `prim`).
fn group_closest(g: u32, r_in: Ray, prim: ptr<function, u32>) -> f32 {
    let gr = group(g);
    var r = r_in;
    var best = FAR;
    var acc = 1.0;
    if gr.has_cw != 0u {
        var slot = 0u;
        let t = cw_traverse(gr, r, false, &acc, &slot);
        if t < FAR {
            best = t;
            *prim = slot;
            r.tmax = t;
        }
    }
    if gr.abvh_base != NONE {
        var slot = 0u;
        let t = b2_traverse(false, P.b2_at + 2u * gr.abvh_base, gr.analytic_base, r, false, &acc, &slot);
        if t < FAR {
            best = t;
            *prim = ANALYTIC_BIT | slot;
        }
    } else {
        for (var i = 0u; i < gr.analytic_count; i++) {
            let t = analytic_intersect(gr.analytic_base + i, r);
            if t < r.tmax {
                r.tmax = t;
                best = t;
                *prim = ANALYTIC_BIT | i;
            }
        }
    }
    return best;
}

// Whether something opaque in group `g` blocks `r`; transmissive hits multiply `acc`.
fn group_occluded(g: u32, r: Ray, acc: ptr<function, f32>) -> bool {
    let gr = group(g);
    var unused = 0u;
    if gr.has_cw != 0u {
        if cw_traverse(gr, r, true, acc, &unused) == 0.0 {
            return true;
        }
    }
    if gr.abvh_base != NONE {
        return b2_traverse(false, P.b2_at + 2u * gr.abvh_base, gr.analytic_base, r, true, acc, &unused) == 0.0;
    }
    for (var i = 0u; i < gr.analytic_count; i++) {
        if leaf_test(false, gr.analytic_base, i, r, true, acc) == 0.0 {
            return true;
        }
    }
    return false;
}

// ---- Instances: 15 vec4 each: inv (4 columns), normal matrix (3), world's linear
// part (3), (group in `groups`, the CPU's group index, moving, 0), d(world)/dt (4
// columns). ----

fn inst_base(i: u32) -> u32 {
    return P.inst_at + 15u * i;
}

// Whether the instance moves now (its d(world)/dt is not zero).
fn inst_moving(i: u32) -> bool {
    return bitcast<u32>(dyn_[inst_base(i) + 10u].z) != 0u;
}

// The world velocity of the instance's local point `p` (`velocity.transform_point3`).
fn inst_velocity(i: u32, p: vec3<f32>) -> vec3<f32> {
    let k = inst_base(i) + 11u;
    return dyn_[k].xyz * p.x + dyn_[k + 1u].xyz * p.y + dyn_[k + 2u].xyz * p.z + dyn_[k + 3u].xyz;
}

// The instance's group in the `groups` table (0 is the static world).
fn inst_group(i: u32) -> u32 {
    return bitcast<u32>(dyn_[inst_base(i) + 10u].x);
}

// The instance's group as the CPU tracer numbers them (its instance groups).
fn inst_cpu_group(i: u32) -> u32 {
    return bitcast<u32>(dyn_[inst_base(i) + 10u].y);
}

fn local_ray(i: u32, r: Ray) -> Ray {
    let k = inst_base(i);
    let c0 = dyn_[k].xyz;
    let c1 = dyn_[k + 1u].xyz;
    let c2 = dyn_[k + 2u].xyz;
    let c3 = dyn_[k + 3u].xyz;
    let o = c0 * r.o.x + c1 * r.o.y + c2 * r.o.z + c3;
    let d = c0 * r.d.x + c1 * r.d.y + c2 * r.d.z;
    return make_ray(o, d, r.tmin, r.tmax);
}

fn inst_mat3(i: u32, first: u32, v: vec3<f32>) -> vec3<f32> {
    let k = inst_base(i) + first;
    return dyn_[k].xyz * v.x + dyn_[k + 1u].xyz * v.y + dyn_[k + 2u].xyz * v.z;
}

// The top level (a Bvh2 over instances, leaves hold the instance index): closest hit,
// or for `shadow` whether something opaque blocks (then returns 0).
fn top_leaf(i: u32, r: ptr<function, Ray>, shadow: bool, acc: ptr<function, f32>, hit: ptr<function, Hit>) -> bool {
    let local = local_ray(i, *r);
    if shadow {
        let before = *acc;
        let blocked = group_occluded(inst_group(i), local, acc);
        if (blocked || *acc != before) && inst_moving(i) {
            g_dynamic = true;
        }
        return !blocked;
    }
    var prim = 0u;
    let t = group_closest(inst_group(i), local, &prim);
    if t < (*r).tmax {
        *hit = Hit(t, INSTANCE, i, prim);
        (*r).tmax = t;
    }
    return true;
}

fn top_traverse(r_in: Ray, shadow: bool, acc: ptr<function, f32>, hit: ptr<function, Hit>) -> bool {
    var r = r_in;
    let at = P.top_at;
    let root_lo = dyn_[at];
    let root_hi = dyn_[at + 1u];
    if !(box_intersect(root_lo.xyz, root_hi.xyz, r) < r.tmax) {
        return true;
    }
    if bitcast<u32>(root_lo.w) != 0u {
        return top_leaf(bitcast<u32>(root_hi.w), &r, shadow, acc, hit);
    }
    var stack: array<u32, STACK2>;
    var sp = 0u;
    var current = bitcast<u32>(root_hi.w);
    loop {
        var l_lo = dyn_[at + 2u * current];
        var l_hi = dyn_[at + 2u * current + 1u];
        var r_lo = dyn_[at + 2u * current + 2u];
        var r_hi = dyn_[at + 2u * current + 3u];
        var lt = box_intersect(l_lo.xyz, l_hi.xyz, r);
        var rt = box_intersect(r_lo.xyz, r_hi.xyz, r);
        if lt > rt {
            let a = l_lo; l_lo = r_lo; r_lo = a;
            let b = l_hi; l_hi = r_hi; r_hi = b;
            let c = lt; lt = rt; rt = c;
        }
        var go_left = lt < r.tmax;
        if go_left && bitcast<u32>(l_lo.w) != 0u {
            if !top_leaf(bitcast<u32>(l_hi.w), &r, shadow, acc, hit) {
                return false;
            }
            go_left = false;
        }
        var go_right = rt < r.tmax;
        if go_right && bitcast<u32>(r_lo.w) != 0u {
            if !top_leaf(bitcast<u32>(r_hi.w), &r, shadow, acc, hit) {
                return false;
            }
            go_right = false;
        }
        if !b2_next(go_left, go_right, bitcast<u32>(l_hi.w), bitcast<u32>(r_hi.w), &stack, &sp, &current) {
            break;
        }
    }
    return true;
}

// ---- The scene (Tracer::closest / Tracer::shadow) ----

fn closest(ray: Ray) -> Hit {
    var best = no_hit();
    var r = ray;
    var prim = 0u;
    let ts = group_closest(0u, r, &prim);
    if ts < FAR {
        best = Hit(ts, STATIC, 0u, prim);
        r.tmax = ts;
    }
    var acc = 1.0;
    if P.top_at != NONE {
        top_traverse(r, false, &acc, &best);
        if best.kind != MISS {
            r.tmax = best.t;
        }
    }
    if P.anim_nodes_at != NONE {
        var slot = 0u;
        let t = b2_traverse(true, P.anim_nodes_at, 0u, r, false, &acc, &slot);
        if t < FAR {
            best = Hit(t, ANIM, 0u, slot);
        }
    }
    return best;
}

// Transmission along a shadow ray: 0 when something opaque blocks it.
fn shadow(r: Ray) -> f32 {
    var acc = 1.0;
    if group_occluded(0u, r, &acc) {
        return 0.0;
    }
    var unused = no_hit();
    if P.top_at != NONE {
        if !top_traverse(r, true, &acc, &unused) {
            return 0.0;
        }
    }
    if P.anim_nodes_at != NONE {
        var slot = 0u;
        if b2_traverse(true, P.anim_nodes_at, 0u, r, true, &acc, &slot) == 0.0 {
            return 0.0;
        }
    }
    return acc;
}

// ---- Surfaces (Tracer::surface, Tracer::uv_density) ----

struct Surface {
    p: vec3<f32>,
    ng: vec3<f32>,
    n: vec3<f32>,
    uv: vec2<f32>,
    material: u32,
    uv_density: f32,
    velocity: vec3<f32>,
    // Instance: the local point; morphing triangle: (u, v, 0); else zero.
    anchor: vec3<f32>,
}

// A rigid group's primitive seen by the (local) ray `lr` at `t`.
fn group_surface(g: u32, prim: u32, lr: Ray, t: f32) -> Surface {
    let pl = lr.o + lr.d * t;
    let gr = group(g);
    if (prim & ANALYTIC_BIT) != 0u {
        let i = gr.analytic_base + (prim & ~ANALYTIC_BIT);
        let n = analytic_normal(i, pl);
        return Surface(pl, n, n, vec2<f32>(0.0), analytic_material(i), 0.0, vec3<f32>(0.0), vec3<f32>(0.0));
    }
    let slot = gr.tri_base + prim;
    let tk = P.tris_at + 4u * slot;
    let bc = tri_barycentric(false, tk, lr);
    let u = bc.x;
    let v = bc.y;
    let w = 1.0 - u - v;
    let ng = -normalize_or(data[tk + 3u].xyz, vec3<f32>(0.0));
    let ak = P.attrs_at + 4u * slot;
    let a0 = data[ak];
    let a1 = data[ak + 1u];
    let a2 = data[ak + 2u];
    let a3 = data[ak + 3u];
    let n = normalize_or(a0.xyz * w + a1.xyz * u + a2.xyz * v, ng);
    let uv = vec2<f32>(a0.w, a1.w) * w + vec2<f32>(a2.w, a3.x) * u + a3.yz * v;
    return Surface(pl, ng, n, uv, bitcast<u32>(a3.w), 0.0, vec3<f32>(0.0), vec3<f32>(0.0));
}

// UV area per unit world area of a rigid group's triangle; `inst` NONE: static.
fn uv_density(g: u32, prim: u32, inst: u32) -> f32 {
    if (prim & ANALYTIC_BIT) != 0u {
        return 0.0;
    }
    let slot = group(g).tri_base + prim;
    let ak = P.attrs_at + 4u * slot;
    let uv0 = vec2<f32>(data[ak].w, data[ak + 1u].w);
    let uv1 = vec2<f32>(data[ak + 2u].w, data[ak + 3u].x);
    let uv2 = data[ak + 3u].yz;
    let e1 = uv1 - uv0;
    let e2 = uv2 - uv0;
    let uv_area2 = abs(e1.x * e2.y - e1.y * e2.x);
    let tk = P.tris_at + 4u * slot;
    var world_area2: f32;
    if inst == NONE {
        world_area2 = length(data[tk + 3u].xyz);
    } else {
        world_area2 = length(cross(inst_mat3(inst, 7u, data[tk + 1u].xyz), inst_mat3(inst, 7u, data[tk + 2u].xyz)));
    }
    if world_area2 > 0.0 {
        return uv_area2 / world_area2;
    }
    return 0.0;
}

fn surface(ray: Ray, h: Hit) -> Surface {
    let p_world = ray.o + ray.d * h.t;
    if h.kind == STATIC {
        var s = group_surface(0u, h.prim, ray, h.t);
        s.p = p_world;
        s.uv_density = uv_density(0u, h.prim, NONE);
        return s;
    }
    if h.kind == INSTANCE {
        let g = inst_group(h.inst);
        var s = group_surface(g, h.prim, local_ray(h.inst, ray), h.t);
        s.velocity = inst_velocity(h.inst, s.p);
        s.anchor = s.p;
        s.p = p_world;
        s.ng = normalize_or(inst_mat3(h.inst, 4u, s.ng), vec3<f32>(0.0, 1.0, 0.0));
        s.n = normalize_or(inst_mat3(h.inst, 4u, s.n), vec3<f32>(0.0, 1.0, 0.0));
        s.uv_density = uv_density(g, h.prim, h.inst);
        return s;
    }
    let tk = P.anim_tris_at + 4u * h.prim;
    let bc = tri_barycentric(true, tk, ray);
    let u = bc.x;
    let v = bc.y;
    let w = 1.0 - u - v;
    let ng = -normalize_or(dyn_[tk + 3u].xyz, vec3<f32>(0.0));
    let ak = P.anim_attr_at + ANIM_VEC4S * h.prim;
    let n = normalize_or(dyn_[ak].xyz * w + dyn_[ak + 1u].xyz * u + dyn_[ak + 2u].xyz * v, ng);
    let velocity = dyn_[ak + 3u].xyz * w + dyn_[ak + 4u].xyz * u + dyn_[ak + 5u].xyz * v;
    return Surface(p_world, ng, n, vec2<f32>(0.0), bitcast<u32>(dyn_[ak].w), 0.0, velocity, vec3<f32>(u, v, 0.0));
}

// ---- Textures (scene/texture.rs: bilinear, repeat wrap, trilinear between levels) ----

fn rem1(x: f32) -> f32 {
    let r = x % 1.0;
    if r < 0.0 {
        return r + 1.0;
    }
    return r;
}

fn texel(level: u32, x: i32, y: i32) -> vec3<f32> {
    let k = P.levels_at + 4u * level;
    let w = i32(words[k]);
    let h = i32(words[k + 1u]);
    let xi = ((x % w) + w) % w;
    let yi = ((y % h) + h) % h;
    return data[P.texels_at + words[k + 2u] + u32(yi * w + xi)].xyz;
}

fn lerp3(a: vec3<f32>, b: vec3<f32>, s: f32) -> vec3<f32> {
    return a * (1.0 - s) + b * s;
}

fn bilinear(level: u32, uv: vec2<f32>) -> vec3<f32> {
    let k = P.levels_at + 4u * level;
    let x = rem1(uv.x) * f32(words[k]) - 0.5;
    let y = (1.0 - rem1(uv.y)) * f32(words[k + 1u]) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi = i32(x0);
    let yi = i32(y0);
    let a = lerp3(texel(level, xi, yi), texel(level, xi + 1, yi), fx);
    let b = lerp3(texel(level, xi, yi + 1), texel(level, xi + 1, yi + 1), fx);
    return lerp3(a, b, fy);
}

// cones::texture_lod.
fn texture_lod(width: f32, cos_incidence: f32, texels: f32, density: f32) -> f32 {
    let c = clamp(abs(cos_incidence), MIN_COS, 1.0);
    let x = texels * density * (width * width) / (c * c);
    if x > 0.0 && x < FAR {
        return 0.5 * log2(x);
    }
    return 0.0;
}

// Texture `tex` at `uv`; `lod` < 0: unfiltered (level 0).
fn sample_texture(tex: u32, uv: vec2<f32>, lod_in: f32) -> vec3<f32> {
    let first = words[P.textures_at + 2u * tex];
    let levels = words[P.textures_at + 2u * tex + 1u];
    let top = f32(levels - 1u);
    let lod = min(max(lod_in, 0.0), top);
    let l0 = floor(lod);
    let f = lod - l0;
    let a = bilinear(first + u32(l0), uv);
    if f == 0.0 {
        return a;
    }
    return lerp3(a, bilinear(first + u32(l0) + 1u, uv), f);
}

// ---- Shading (shade.rs) ----

fn reflect_cpu(d: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return d - 2.0 * dot(d, n) * n;
}

fn epsilon(p: vec3<f32>) -> f32 {
    return 1e-5 * max(P.du.w, max3(abs(p)));
}

// A pending ray of the Whitted tree: where it starts, its weight in the sample's
// colour, its cone (width at the origin, spread) and its depth.
struct Pending {
    o: vec3<f32>,
    d: vec3<f32>,
    weight: vec3<f32>,
    cone_width: f32,
    depth: u32,
}

struct Local {
    color: vec3<f32>,
    // Secondary rays: refraction (weight 0 when none) and reflection.
    refr: Pending,
    refl: Pending,
}

// Also counts the shadow rays it traces in `rays`.
fn direct_light(mi: u32, p_out: vec3<f32>, eps: f32, n: vec3<f32>, ng: vec3<f32>, d: vec3<f32>, diffuse: vec3<f32>, rays: ptr<function, u32>) -> vec3<f32> {
    var color = vec3<f32>(0.0);
    let mk = P.materials_at + 4u * mi;
    let specular = data[mk + 2u].xyz;
    let shininess = data[mk].w;
    for (var i = 0u; i < P.n_lights; i++) {
        let lp = dyn_[P.lights_at + 2u * i].xyz;
        let lc = dyn_[P.lights_at + 2u * i + 1u].xyz;
        var l = lp - p_out;
        let dist = sqrt(dot(l, l));
        if dist <= eps {
            continue;
        }
        l = l / dist;
        let ndl = dot(n, l);
        if ndl <= 0.0 || dot(ng, l) <= 0.0 {
            continue;
        }
        let vis = shadow(make_ray(p_out, l, 0.0, dist * (1.0 - 1e-5)));
        *rays += 1u;
        if vis <= 0.0 {
            continue;
        }
        var c = diffuse * ndl;
        if max3(specular) > 0.0 {
            let rv = dot(reflect_cpu(-l, n), -d);
            if rv > 0.0 {
                c += specular * pow(rv, max(shininess, 0.0));
            }
        }
        color += lc * vis * c;
    }
    return color;
}

// Tracer::shade at a hit, without the recursion: the local colour and the secondary
// rays it asks for (weights relative to this hit's).
fn shade(ray: Ray, s: Surface, cone_width: f32, depth: u32, rays: ptr<function, u32>) -> Local {
    var res: Local;
    res.refr.weight = vec3<f32>(0.0);
    res.refl.weight = vec3<f32>(0.0);
    if any(s.velocity != vec3<f32>(0.0)) {
        g_dynamic = true;
    }
    if s.material >= P.n_materials {
        res.color = vec3<f32>(1.0, 0.0, 1.0);
        return res;
    }
    let mk = P.materials_at + 4u * s.material;
    let m_ambient = data[mk].xyz;
    let m_diffuse = data[mk + 1u].xyz;
    let transmission = data[mk + 1u].w;
    let specular = data[mk + 2u].xyz;
    let ior = data[mk + 2u].w;
    let tex_id = bitcast<u32>(data[mk + 3u].x);
    let d = normalize_cpu(ray.d);
    let entering = dot(s.ng, d) < 0.0;
    let ng = select(-s.ng, s.ng, entering);
    var n = select(-s.n, s.n, entering);
    if dot(n, d) > 0.0 {
        n = ng;
    }
    var tex = vec3<f32>(1.0);
    if tex_id != NONE {
        var lod = 0.0;
        if P.ray_cones != 0u {
            lod = texture_lod(cone_width, dot(d, ng), bitcast<f32>(data[mk + 3u].y), s.uv_density);
        }
        tex = sample_texture(tex_id, s.uv, lod);
    }
    var color = P.ambient.xyz * m_ambient * tex;
    let eps = epsilon(s.p);
    let p_out = s.p + ng * eps;
    color += direct_light(s.material, p_out, eps, n, ng, d, m_diffuse * tex, rays);
    res.color = color;
    if depth >= P.max_depth {
        return res;
    }
    var mirror = select(vec3<f32>(0.0), specular, max3(specular) > 0.0);
    if transmission > 0.0 {
        let eta = select(ior, 1.0 / ior, entering);
        let cos_i = -dot(d, n);
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        if k >= 0.0 {
            let t_dir = normalize_cpu(eta * d + (eta * cos_i - sqrt(k)) * n);
            res.refr = Pending(s.p - ng * eps, t_dir, vec3<f32>(transmission), cone_width, depth + 1u);
        } else {
            mirror += vec3<f32>(transmission);
        }
    }
    if max3(mirror) > 0.0 {
        res.refl = Pending(p_out, reflect_cpu(d, n), mirror, cone_width, depth + 1u);
    }
    return res;
}

// Writes sample `i`'s output.
fn write_out(i: u32, color: vec3<f32>, t: f32, id: vec4<u32>, p: vec3<f32>, velocity: vec3<f32>, anchor: vec3<f32>) {
    if P.colour_only != 0u {
        out[i] = vec4<u32>(bitcast<vec3<u32>>(color), bitcast<u32>(t));
        return;
    }
    let k = OUT_VEC4S * i;
    out[k] = vec4<u32>(bitcast<vec3<u32>>(color), bitcast<u32>(t));
    out[k + 1u] = id;
    out[k + 2u] = vec4<u32>(bitcast<vec3<u32>>(p), 0u);
    out[k + 3u] = vec4<u32>(bitcast<vec3<u32>>(velocity), 0u);
    out[k + 4u] = vec4<u32>(bitcast<vec3<u32>>(anchor), 0u);
}

@compute @workgroup_size(64)
fn trace(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= P.count {
        return;
    }
    g_dynamic = false;
    let xy = points[i];
    let dir = normalize_cpu(P.corner.xyz + P.du.xyz * xy.x + P.dv.xyz * xy.y);
    let primary = make_ray(P.eye.xyz, dir, max(P.eye.w, 0.0), FAR);
    let h = closest(primary);
    var id = vec4<u32>(h.kind, 0u, h.prim, 0u);
    if h.kind == INSTANCE {
        id.y = inst_cpu_group(h.inst);
    }
    if h.kind == MISS || P.primary_only != 0u {
        // Tracer::sample on a miss: the ray's point a million units out.
        let far = primary.o + primary.d * 1e6;
        write_out(i, P.background.xyz, h.t, id, far, vec3<f32>(0.0), vec3<f32>(0.0));
        return;
    }
    var color = vec3<f32>(0.0);
    var stack: array<Pending, STACK>;
    var sp = 0u;
    // The primary hit is shaded first; then the pending secondary rays, depth first.
    var ray = primary;
    var hit = h;
    var weight = vec3<f32>(1.0);
    var cone_width = 0.0;
    var depth = 0u;
    var rays = 0u;
    var first: Surface;
    var is_first = true;
    loop {
        if hit.kind == MISS {
            color += weight * P.background.xyz;
        } else {
            let s = surface(ray, hit);
            if is_first {
                first = s;
                is_first = false;
            }
            let width = cone_width + P.corner.w * hit.t;
            let local = shade(ray, s, width, depth, &rays);
            color += weight * local.color;
            if max3(local.refl.weight) > 0.0 && sp < STACK {
                stack[sp] = local.refl;
                stack[sp].weight *= weight;
                sp++;
            }
            if max3(local.refr.weight) > 0.0 && sp < STACK {
                stack[sp] = local.refr;
                stack[sp].weight *= weight;
                sp++;
            }
        }
        if sp == 0u {
            break;
        }
        sp--;
        let next = stack[sp];
        ray = make_ray(next.o, next.d, 0.0, FAR);
        hit = closest(ray);
        rays += 1u;
        weight = next.weight;
        cone_width = next.cone_width;
        depth = next.depth;
    }
    id.w = rays | select(0u, DYNAMIC_BIT, g_dynamic);
    write_out(i, color, h.t, id, first.p, first.velocity, first.anchor);
}
