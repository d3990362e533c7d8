// The carry step on the accumulators the GPU kept from its last refresh, so that the
// carried sums need not come up from the CPU again: the CPU carries its own copy of
// the sums the same way, and lists here what it did (the decay factors of every
// tile, the pixels whose sums moved and where they landed, the pixels it cut). The
// same operations in the same order as the CPU's carry (`carry.rs`):
//
// decay   one thread per pixel: every sum by its tile's factor, the weighted age
//         first grown by `dt` per unit weight, the coverage by its own factor.
// take    one thread per moving pixel: its sums set aside, the pixel emptied.
// land    one thread: the set-aside sums land one after another, each replacing or
//         added to what its pixel holds (as the CPU decided: it knows the weights and
//         the geometry), in the CPU's order, so that pixels landed on twice agree.
// cut     one thread per cut pixel: emptied (a new sample came in front).
//
// After a refresh's splats, `holds_mask` gives the CPU what its carry decides from: a
// bit per pixel, whether its weight holds sums (at least `MIN_WEIGHT`), instead of the
// sums themselves.
//
// `PER_PIXEL` and `MIN_WEIGHT` are prepended by the Rust side, which shares them.

struct CarryParams {
    pixels: u32,
    takes: u32,
    lands: u32,
    cuts: u32,
    dt: f32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> C: CarryParams;
// Per pixel: weighted red, green, blue, weight, weighted age, carried coverage.
@group(0) @binding(1) var<storage, read_write> acc: array<f32>;
@group(0) @binding(2) var<storage, read> pix_tile: array<u32>;
// Per tile: the decay of the sums and of the coverage over `dt`.
@group(0) @binding(3) var<storage, read> decay: array<vec2<f32>>;
// The taken pixels, then per landing (index of the taken sums, pixel, 1 to add),
// then the cut pixels.
@group(0) @binding(4) var<storage, read> edits: array<u32>;
// The taken sums, `PER_PIXEL` floats each.
@group(0) @binding(5) var<storage, read_write> taken: array<f32>;
// Bit `i` of word `k`: pixel `32k + i` holds sums.
@group(0) @binding(6) var<storage, read_write> holds: array<u32>;

@compute @workgroup_size(256)
fn decay_sums(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if p >= C.pixels {
        return;
    }
    let f = decay[pix_tile[p]];
    let b = p * PER_PIXEL;
    let w = acc[b + 3u];
    acc[b + 4u] = f.x * fma(C.dt, w, acc[b + 4u]);
    acc[b + 3u] = w * f.x;
    for (var c = 0u; c < 3u; c++) {
        acc[b + c] = acc[b + c] * f.x;
    }
    acc[b + 5u] = acc[b + 5u] * f.y;
}

@compute @workgroup_size(256)
fn take_sums(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= C.takes {
        return;
    }
    let b = edits[i] * PER_PIXEL;
    for (var c = 0u; c < PER_PIXEL; c++) {
        taken[i * PER_PIXEL + c] = acc[b + c];
        acc[b + c] = 0.0;
    }
}

@compute @workgroup_size(1)
fn land_sums() {
    let first = C.takes;
    for (var j = 0u; j < C.lands; j++) {
        let e = first + 3u * j;
        let src = edits[e] * PER_PIXEL;
        let to = edits[e + 1u] * PER_PIXEL;
        let merge = edits[e + 2u] != 0u;
        for (var c = 0u; c < PER_PIXEL; c++) {
            let v = taken[src + c];
            acc[to + c] = select(v, acc[to + c] + v, merge);
        }
    }
}

@compute @workgroup_size(256)
fn cut_sums(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= C.cuts {
        return;
    }
    let b = edits[C.takes + 3u * C.lands + i] * PER_PIXEL;
    for (var c = 0u; c < PER_PIXEL; c++) {
        acc[b + c] = 0.0;
    }
}

@compute @workgroup_size(256)
fn holds_mask(@builtin(global_invocation_id) gid: vec3<u32>) {
    let first = gid.x * 32u;
    if first >= C.pixels {
        return;
    }
    var bits = 0u;
    for (var i = 0u; i < 32u; i++) {
        let p = first + i;
        if p < C.pixels && acc[p * PER_PIXEL + 3u] >= MIN_WEIGHT {
            bits |= 1u << i;
        }
    }
    holds[gid.x] = bits;
}
