// The reconstructor's refresh in compute shaders: the same steps and the same
// arithmetic as the CPU reconstructor, with the splat turned into a gather.
//
// place   one thread per live ring sample: reprojection, the pixel's tile filter and
//         splat scale, the temporal cull, the footprint box; counts the footprint in
//         every 16×16 bin of pixels it touches.
// scan    one workgroup: each bin's first item (exclusive prefix sum of the counts).
// fill    one thread per splat: its index into each bin it touches.
// sort    one workgroup per bin: the bin's splat indices in ring order, so that every
//         pixel adds its splats in the order the CPU does, whatever order the atomic
//         counters handed out the slots in (the image is the same at every run).
// gather  one thread per pixel: the Gaussian weights of its bin's splats, added to the
//         sums carried from the previous refresh when carrying.
// resolve one thread per pixel: quotients, coverage, the next splat scale.
//
// `BIN`, `MIN_WEIGHT` and `PER_PIXEL` are prepended by the Rust side, which shares them.
// pull    one thread per block of a pyramid level: 2×2 sums of the level below.
// holes   one thread per pixel: a pixel no splat reached takes the mean of the
//         smallest pyramid block around it that has samples.

struct Params {
    eye: vec3<f32>,
    t: f32,
    forward: vec3<f32>,
    reproject: u32,
    u: vec3<f32>,
    ou: f32,
    v: vec3<f32>,
    ov: f32,
    width: u32,
    height: u32,
    cap: u32,
    // Physical ring index of the first live sample.
    first: u32,
    count: u32,
    bins_x: u32,
    bins_y: u32,
    items_cap: u32,
    temporal_cutoff: f32,
    max_r: f32,
    grow: f32,
    shrink: f32,
    undersampled: u32,
    oversampled: u32,
    scale_lo: f32,
    scale_hi: f32,
    levels: u32,
    // `1 / (1 + depth tolerance)` of the visibility pass, 0 without it.
    keep: f32,
    // Moving samples set front depths while `age / e_t` is at most this.
    setter_age: f32,
    // Weight below which the pull-push fill completes a pixel, 0 without it.
    fill_weight: f32,
    // Nonzero: `acc` holds the sums carried from the previous refresh, and its last
    // float per pixel the carried coverage (a float) instead of this refresh's count.
    carry: u32,
    // Tiles of this refresh's filter table.
    tiles: u32,
    // While the view moves: each front-setting sample lowers its eight neighbours'
    // fronts to this many times its depth; 0: it sets its own pixel's only.
    spread: f32,
    // Refreshes in `eyes`.
    track: u32,
    // While the fronts spread, a far sample behind a spread front is hidden only if the
    // view's motion moved it this many pixels across the near surface.
    parallax: f32,
    // While the fronts spread, a far sample is also hidden where a front this many times
    // nearer lies in its footprint's box (0: not) and the view's motion moved it
    // `footprint_parallax` pixels across it; the box widened by as many pixels as that
    // motion, up to `footprint_reach`.
    footprint: f32,
    footprint_parallax: f32,
    footprint_reach: f32,
    // When the newest sample in hand was traced (relative to the epoch, as `t`): the
    // temporal filter measures ages from it.
    t_newest: f32,
}

struct TileFilter {
    inv_et: f32,
    ax: f32,
    ay: f32,
    cx: f32,
    cy: f32,
    // The tile's rectangle on the image, clipped to it (right and bottom exclusive).
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    pad0: f32,
    pad1: f32,
    pad2: f32,
}

// A sample ready to splat; `x0 > x1` marks one culled.
struct Splat {
    x: f32,
    y: f32,
    ax: f32,
    ay: f32,
    // Temporal weight × (red, green, blue, 1).
    c: vec4<f32>,
    // Temporal weight × age.
    age: f32,
    x0: i32,
    x1: i32,
    y0: i32,
    y1: i32,
    // Depth in the current view, and the pixel it lands in (`OUTSIDE` off the image;
    // both for the visibility pass only).
    z: f32,
    pixel: u32,
    pad: f32,
}

struct Level {
    // Offset of the level below in `pyramid` (in blocks), 0 for level 1 (read from
    // `acc`), and of this level.
    src: u32,
    dst: u32,
    src_w: u32,
    src_h: u32,
    dst_w: u32,
    dst_h: u32,
    from_acc: u32,
    pad0: u32,
}

const OUTSIDE: u32 = 0xffffffffu;
// Fields of the ring, one run of `cap` floats each (as the CPU ring's arrays).
const X: u32 = 0u;
const Y: u32 = 1u;
const R: u32 = 2u;
const HX: u32 = 5u;
const VX: u32 = 8u;
const T: u32 = 11u;

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> ring: array<f32>;
@group(0) @binding(2) var<storage, read> tiles: array<TileFilter>;
@group(0) @binding(3) var<storage, read_write> pix_tile: array<u32>;
@group(0) @binding(4) var<storage, read_write> scale: array<f32>;
@group(0) @binding(5) var<storage, read_write> splats: array<Splat>;
// Per bin: counts, then cursors; then the total of items and the hole count.
@group(0) @binding(6) var<storage, read_write> bins: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read_write> bin_start: array<u32>;
@group(0) @binding(8) var<storage, read_write> items: array<u32>;
// Per pixel: weighted red, green, blue, weight, weighted age, then this refresh's
// coverage (bits), or when carrying the carried coverage plus it (a float).
@group(0) @binding(9) var<storage, read_write> acc: array<f32>;
// Per pixel: red, green, blue, age, coverage (bits), splat scale.
@group(0) @binding(10) var<storage, read_write> out: array<f32>;
// Pyramid levels 1 and up, 5 floats per block (the accumulator's first five).
@group(0) @binding(11) var<storage, read_write> pyramid: array<f32>;
// Per pixel: the nearest depth a front-setting sample gives it, as the complement of
// its bits (depths are positive, so the largest complement is the nearest depth, and
// a cleared buffer, 0, means none). When carrying it starts from the depths of the
// still carried sums, so that new samples behind them are hidden as on the CPU.
// While the fronts spread, the pixels' own fronts follow, from `width · height` on, and
// with a footprint's spread their pyramid's levels 1 and up, from `2 · width · height`
// on (the pull pyramid's levels; each block the nearest of the four below it).
@group(0) @binding(12) var<storage, read_write> front: array<atomic<u32>>;
// The eye at the recent refreshes, `P.track` of them newest first: (age, position).
@group(0) @binding(13) var<storage, read> eyes: array<vec4<f32>>;
@group(1) @binding(0) var<uniform> L: Level;

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn ring_at(field: u32, p: u32) -> f32 {
    return ring[field * P.cap + p];
}

fn bin_count() -> u32 {
    return P.bins_x * P.bins_y;
}

fn empty_splat() -> Splat {
    var s: Splat;
    s.x0 = 1;
    s.x1 = 0;
    s.y0 = 1;
    s.y1 = 0;
    s.pixel = OUTSIDE;
    return s;
}

// Whether depth `z` lies behind the front depth of pixel `p` (beyond the tolerance).
fn hidden(p: u32, z: f32) -> bool {
    return behind(atomicLoad(&front[p]), z);
}

// Whether depth `z` lies behind the front `f` (complemented bits; 0: none).
fn behind(f: u32, z: f32) -> bool {
    return f != 0u && bitcast<f32>(~f) < z * P.keep;
}

// Whether splat `s` of live sample `i` is hidden: behind its pixel's front; while the
// fronts spread, behind its own front, or behind the spread one with the parallax that
// moved it there (the CPU's `SpreadView::hides`).
fn splat_hidden(i: u32, s: Splat) -> bool {
    if P.spread <= 0.0 {
        return hidden(s.pixel, s.z);
    }
    if behind(atomicLoad(&front[P.width * P.height + s.pixel]), s.z) {
        return true;
    }
    let f = atomicLoad(&front[s.pixel]);
    if behind(f, s.z) && parallax_of(i, s, bitcast<f32>(~f) / P.spread) >= P.parallax {
        return true;
    }
    if P.footprint > 0.0 {
        return footprint_hides(i, s);
    }
    return false;
}

// Whether a front `P.footprint` times nearer than splat `s` of live sample `i` lies in
// its footprint's box widened by the pixels the view's motion carried it across that
// front (at most `P.footprint_reach`), with that motion `P.footprint_parallax` pixels
// or more (the CPU's `SpreadView::footprint_hides`).
fn footprint_hides(i: u32, s: Splat) -> bool {
    let wide = widened(s, u32(P.footprint_reach));
    if within_neighbours(s, wide) {
        return false;
    }
    let m = nearest_in(wide);
    if !far_behind(m, s.z) {
        return false;
    }
    let moved = parallax_of(i, s, bitcast<f32>(~m));
    if moved < P.footprint_parallax {
        return false;
    }
    return moved >= P.footprint_reach || far_behind(nearest_in(widened(s, u32(moved))), s.z);
}

// Whether depth `z` lies behind `P.footprint` times the front `m` (complemented bits;
// 0: none).
fn far_behind(m: u32, z: f32) -> bool {
    return m != 0u && P.footprint * bitcast<f32>(~m) < z * P.keep;
}

// Splat `s`'s footprint box `[x0, x1, y0, y1]` widened by `by` pixels each way, within
// the image.
fn widened(s: Splat, by: u32) -> vec4<u32> {
    return vec4<u32>(
        u32(max(s.x0 - i32(by), 0)),
        min(u32(s.x1) + by, P.width - 1u),
        u32(max(s.y0 - i32(by), 0)),
        min(u32(s.y1) + by, P.height - 1u),
    );
}

// Whether the box `b` lies within splat `s`'s landing pixel and the eight around it,
// where the spread, not the footprint's, decides.
fn within_neighbours(s: Splat, b: vec4<u32>) -> bool {
    let px = u32(s.x);
    let py = u32(s.y);
    return b.x + 1u >= px && b.y <= px + 1u && b.z + 1u >= py && b.w <= py + 1u;
}

// The nearest own front over the box `b` (`[x0, x1, y0, y1]`) and the pixels around it
// (complemented bits, 0: none): over the at most 2×2 blocks of the lowest level (the
// own fronts first) in which the box spans two blocks or fewer each way (the CPU's
// `SpreadView::nearest_in`).
fn nearest_in(b: vec4<u32>) -> u32 {
    let n = P.width * P.height;
    var x0 = b.x;
    var x1 = b.y;
    var y0 = b.z;
    var y1 = b.w;
    var w = P.width;
    var h = P.height;
    var base = n;
    var next = 2u * n;
    while (x1 - x0 > 1u || y1 - y0 > 1u) && (w > 1u || h > 1u) {
        w = (w + 1u) / 2u;
        h = (h + 1u) / 2u;
        base = next;
        next += w * h;
        x0 >>= 1u;
        x1 >>= 1u;
        y0 >>= 1u;
        y1 >>= 1u;
    }
    var m = 0u;
    for (var y = y0; y <= y1; y++) {
        for (var x = x0; x <= x1; x++) {
            m = max(m, atomicLoad(&front[base + y * w + x]));
        }
    }
    return m;
}

// A level of the own fronts' pyramid from the one below (level 0: the own fronts).
@compute @workgroup_size(256)
fn front_pull(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= L.dst_w * L.dst_h {
        return;
    }
    let n = P.width * P.height;
    var below = 2u * n + L.src;
    if L.from_acc != 0u {
        below = n;
    }
    let cx = i % L.dst_w;
    let cy = i / L.dst_w;
    var m = 0u;
    for (var y = 2u * cy; y < min(2u * cy + 2u, L.src_h); y++) {
        for (var x = 2u * cx; x < min(2u * cx + 2u, L.src_w); x++) {
            m = max(m, atomicLoad(&front[below + y * L.src_w + x]));
        }
    }
    atomicStore(&front[2u * n + L.dst + i], m);
}

// The eye `age` seconds before this refresh, linear between the refreshes around it.
fn eye_at(age: f32) -> vec3<f32> {
    let n = P.track;
    if n == 0u {
        return vec3<f32>(0.0);
    }
    var lo = 0u;
    var hi = n;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if eyes[mid].x <= age {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    if lo == 0u {
        return eyes[0].yzw;
    }
    if lo == n {
        return eyes[n - 1u].yzw;
    }
    let e0 = eyes[lo - 1u];
    let e1 = eyes[lo];
    return e0.yzw + (e1.yzw - e0.yzw) * ((age - e0.x) / (e1.x - e0.x));
}

// How far the view's motion since live sample `i` was traced moved it (splat `s`) from
// the point at depth `near` on the ray it was traced along, in pixels (the CPU's
// `Viewpoint::parallax_of`).
fn parallax_of(i: u32, s: Splat, near: f32) -> f32 {
    let inf = bitcast<f32>(0x7f800000u);
    let p = live_slot(i);
    let world = world_at(p, P.t - ring_at(T, p));
    let origin = eye_at(s.age / s.c.w);
    let along = dot(world - origin, P.forward);
    let reach = (near - dot(origin - P.eye, P.forward)) / along;
    if !(along > 0.0) || !(reach > 0.0) {
        return inf;
    }
    let v = view_of(origin + (world - origin) * reach - P.eye);
    if !(v.z > 1e-6) {
        return inf;
    }
    return length(v.xy - vec2<f32>(s.x, s.y));
}

// The ring slot of live sample `i`.
fn live_slot(i: u32) -> u32 {
    var p = P.first + i;
    if p >= P.cap {
        p -= P.cap;
    }
    return p;
}

// Where the sample in ring slot `p` is `dt` seconds after it was traced.
fn world_at(p: u32, dt: f32) -> vec3<f32> {
    let hit = vec3<f32>(ring_at(HX, p), ring_at(HX + 1u, p), ring_at(HX + 2u, p));
    let vel = vec3<f32>(ring_at(VX, p), ring_at(VX + 1u, p), ring_at(VX + 2u, p));
    return hit + vel * dt;
}

// The pixel position and depth in this refresh's view of the offset `d` from the eye
// (the CPU placer's projector).
fn view_of(d: vec3<f32>) -> vec3<f32> {
    let z = dot(d, P.forward);
    let iz = 1.0 / z;
    return vec3<f32>(dot(d, P.u) * iz - P.ou, dot(d, P.v) * iz - P.ov, z);
}

// The pixel → tile map, a workgroup a tile writing its index over its rectangle
// (the rectangles cover the image without overlap).
@compute @workgroup_size(64)
fn paint_tiles(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    let k = wg.y * groups.x + wg.x;
    if k >= P.tiles {
        return;
    }
    let f = tiles[k];
    let w = f.x1 - f.x0;
    let n = w * (f.y1 - f.y0);
    for (var j = li; j < n; j += 64u) {
        pix_tile[(f.y0 + j / w) * P.width + f.x0 + j % w] = k;
    }
}

@compute @workgroup_size(256)
fn place(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= P.count {
        return;
    }
    let p = live_slot(i);
    let dt = P.t - ring_at(T, p);
    var x: f32;
    var y: f32;
    var z = 0.0;
    var in_front = true;
    if P.reproject != 0u {
        let v = view_of(world_at(p, dt) - P.eye);
        x = v.x;
        y = v.y;
        z = v.z;
        in_front = z > 1e-6;
    } else {
        x = ring_at(X, p);
        y = ring_at(Y, p);
    }
    var s = empty_splat();
    if in_front && finite(x) && finite(y) {
        let w = f32(P.width - 1u);
        let h = f32(P.height - 1u);
        let px = u32(floor(min(max(x, 0.0), w)));
        let py = u32(floor(min(max(y, 0.0), h)));
        let pix = py * P.width + px;
        let f = tiles[pix_tile[pix]];
        let age = max(dt, 0.0);
        let a = max(P.t_newest - ring_at(T, p), 0.0) * f.inv_et;
        if a <= P.temporal_cutoff {
            let sc = scale[pix];
            let rx = min(f.cx * sc, P.max_r);
            let ry = min(f.cy * sc, P.max_r);
            let x0 = max(ceil(x - 0.5 - rx), 0.0);
            let x1 = min(floor(x - 0.5 + rx), w);
            let y0 = max(ceil(y - 0.5 - ry), 0.0);
            let y1 = min(floor(y - 0.5 + ry), h);
            if x0 <= x1 && y0 <= y1 {
                let wt = exp(-0.5 * a * a);
                s.x = x;
                s.y = y;
                s.ax = f.ax;
                s.ay = f.ay;
                s.c = wt * vec4<f32>(ring_at(R, p), ring_at(R + 1u, p), ring_at(R + 2u, p), 1.0);
                s.age = wt * age;
                s.x0 = i32(x0);
                s.x1 = i32(x1);
                s.y0 = i32(y0);
                s.y1 = i32(y1);
                if P.keep > 0.0 {
                    set_front(&s, p, a, z);
                }
            }
        }
    }
    splats[i] = s;
}

// The visibility pass's part of placing: where the splat lands, and the front depth
// it sets there if it is still or recent.
fn set_front(s: ptr<function, Splat>, p: u32, a: f32, z: f32) {
    (*s).z = z;
    let x = (*s).x;
    let y = (*s).y;
    if x >= 0.0 && x < f32(P.width) && y >= 0.0 && y < f32(P.height) {
        let pix = u32(y) * P.width + u32(x);
        (*s).pixel = pix;
        let still = ring_at(VX, p) == 0.0 && ring_at(VX + 1u, p) == 0.0 && ring_at(VX + 2u, p) == 0.0;
        if still || a <= P.setter_age {
            atomicMax(&front[pix], ~bitcast<u32>(z));
            if P.spread > 0.0 {
                atomicMax(&front[P.width * P.height + pix], ~bitcast<u32>(z));
                spread_front(u32(x), u32(y), ~bitcast<u32>(P.spread * z));
            }
        }
    }
}

// Lower the fronts of the eight pixels around (`x`, `y`) to the front `bits`: the
// CPU's minimum over each pixel's neighbours, gathered there, scattered here.
fn spread_front(x: u32, y: u32, bits: u32) {
    let x0 = max(x, 1u) - 1u;
    let y0 = max(y, 1u) - 1u;
    let x1 = min(x + 1u, P.width - 1u);
    let y1 = min(y + 1u, P.height - 1u);
    for (var j = y0; j <= y1; j++) {
        for (var i = x0; i <= x1; i++) {
            if i != x || j != y {
                atomicMax(&front[j * P.width + i], bits);
            }
        }
    }
}

// Drop the splats hidden behind a nearer surface (the visibility pass) and count
// every other one in the bins its footprint touches.
@compute @workgroup_size(256)
fn count(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= P.count {
        return;
    }
    let s = splats[i];
    if s.x0 > s.x1 {
        return;
    }
    if P.keep > 0.0 && s.pixel != OUTSIDE && splat_hidden(i, s) {
        splats[i] = empty_splat();
        return;
    }
    for (var by = u32(s.y0) / BIN; by <= u32(s.y1) / BIN; by++) {
        for (var bx = u32(s.x0) / BIN; bx <= u32(s.x1) / BIN; bx++) {
            atomicAdd(&bins[by * P.bins_x + bx], 1u);
        }
    }
}

var<workgroup> partial: array<u32, 256>;

@compute @workgroup_size(256)
fn scan(@builtin(local_invocation_index) li: u32) {
    let nb = bin_count();
    let per = (nb + 255u) / 256u;
    let b0 = min(li * per, nb);
    let b1 = min(b0 + per, nb);
    var sum = 0u;
    for (var b = b0; b < b1; b++) {
        sum += atomicLoad(&bins[b]);
    }
    partial[li] = sum;
    workgroupBarrier();
    for (var off = 1u; off < 256u; off *= 2u) {
        var v = 0u;
        if li >= off {
            v = partial[li - off];
        }
        workgroupBarrier();
        partial[li] += v;
        workgroupBarrier();
    }
    var run = partial[li] - sum;
    for (var b = b0; b < b1; b++) {
        bin_start[b] = run;
        run += atomicLoad(&bins[b]);
        atomicStore(&bins[nb + b], 0u);
    }
    if li == 255u {
        bin_start[nb] = partial[255];
        atomicStore(&bins[2u * nb], partial[255]);
        atomicStore(&bins[2u * nb + 1u], 0u);
    }
}

@compute @workgroup_size(256)
fn fill(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= P.count {
        return;
    }
    let s = splats[i];
    if s.x0 > s.x1 {
        return;
    }
    let nb = bin_count();
    for (var by = u32(s.y0) / BIN; by <= u32(s.y1) / BIN; by++) {
        for (var bx = u32(s.x0) / BIN; bx <= u32(s.x1) / BIN; bx++) {
            let b = by * P.bins_x + bx;
            let slot = bin_start[b] + atomicAdd(&bins[nb + b], 1u);
            if slot < P.items_cap {
                items[slot] = i;
            }
        }
    }
}

var<workgroup> sort_n: u32;
var<workgroup> sort_o: u32;

// A bitonic network whose comparators all put the smaller index first (the first
// step of each merge compares mirrored positions), so the list need not be a power
// of two long: positions past its end act as +∞ and are never moved into it.
@compute @workgroup_size(256)
fn sort(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if li == 0u {
        let b = wid.y * P.bins_x + wid.x;
        let o = min(bin_start[b], P.items_cap);
        sort_o = o;
        sort_n = min(bin_start[b + 1u], P.items_cap) - o;
    }
    let n = workgroupUniformLoad(&sort_n);
    let o = workgroupUniformLoad(&sort_o);
    var m = 1u;
    while m < n {
        m *= 2u;
    }
    for (var k = 2u; k <= m; k *= 2u) {
        for (var j = k / 2u; j > 0u; j /= 2u) {
            for (var i = li; i < m; i += 256u) {
                var q = i ^ j;
                if j == k / 2u {
                    q = i ^ (k - 1u);
                }
                if q > i && q < n {
                    let a = items[o + i];
                    let b = items[o + q];
                    if b < a {
                        items[o + i] = b;
                        items[o + q] = a;
                    }
                }
            }
            storageBarrier();
            workgroupBarrier();
        }
    }
}

@compute @workgroup_size(16, 16)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    if gid.x >= P.width || gid.y >= P.height {
        return;
    }
    let b = wid.y * P.bins_x + wid.x;
    let o = min(bin_start[b], P.items_cap);
    let e = min(bin_start[b + 1u], P.items_cap);
    let cx = f32(gid.x) + 0.5;
    let cy = f32(gid.y) + 0.5;
    let xi = i32(gid.x);
    let yi = i32(gid.y);
    let q = (gid.y * P.width + gid.x) * PER_PIXEL;
    var sum = vec4<f32>(0.0);
    var age = 0.0;
    var cov = 0u;
    if P.carry != 0u {
        sum = vec4<f32>(acc[q], acc[q + 1u], acc[q + 2u], acc[q + 3u]);
        age = acc[q + 4u];
    }
    for (var k = o; k < e; k++) {
        let s = splats[items[k]];
        if xi >= s.x0 && xi <= s.x1 && yi >= s.y0 && yi <= s.y1 {
            let dx = cx - s.x;
            let dy = cy - s.y;
            let gx = exp(-(dx * dx * s.ax));
            let gy = exp(-(dy * dy * s.ay));
            sum += (gx * s.c) * gy;
            age += (gx * s.age) * gy;
            cov += 1u;
        }
    }
    acc[q] = sum.x;
    acc[q + 1u] = sum.y;
    acc[q + 2u] = sum.z;
    acc[q + 3u] = sum.w;
    acc[q + 4u] = age;
    if P.carry != 0u {
        acc[q + 5u] += f32(cov);
    } else {
        acc[q + 5u] = bitcast<f32>(cov);
    }
}

// Coverage of the pixel at `q` in `acc` after `gather`: this refresh's count, or the
// carried coverage plus it rounded half away from zero (Rust's `round`; WGSL's rounds
// half to even). `c - floor(c)` is exact, so halves are found exactly.
fn coverage(q: u32) -> u32 {
    if P.carry == 0u {
        return bitcast<u32>(acc[q + 5u]);
    }
    let c = acc[q + 5u];
    if c - floor(c) == 0.5 {
        return u32(floor(c) + 1.0);
    }
    return u32(round(c));
}

@compute @workgroup_size(256)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>) {
    let pix = gid.x;
    if pix >= P.width * P.height {
        return;
    }
    let q = pix * PER_PIXEL;
    let w = acc[q + 3u];
    let cov = coverage(q);
    var s = scale[pix];
    if cov < P.undersampled {
        s *= P.grow;
    } else if cov > P.oversampled {
        s *= P.shrink;
    }
    s = clamp(s, P.scale_lo, P.scale_hi);
    scale[pix] = s;
    if w >= MIN_WEIGHT {
        out[q] = acc[q] / w;
        out[q + 1u] = acc[q + 1u] / w;
        out[q + 2u] = acc[q + 2u] / w;
        out[q + 3u] = acc[q + 4u] / w;
    } else {
        atomicAdd(&bins[2u * bin_count() + 1u], 1u);
        out[q] = 0.0;
        out[q + 1u] = 0.0;
        out[q + 2u] = 0.0;
        out[q + 3u] = 0.0;
    }
    out[q + 4u] = bitcast<f32>(cov);
    out[q + 5u] = s;
}

// One block of the level below `L`: at level 0 a pixel's own sums (zero for a hole),
// or with the pull-push fill its premultiplied values (`premultiplied`).
fn below(x: u32, y: u32) -> array<f32, 5> {
    var r: array<f32, 5>;
    if L.from_acc != 0u && P.fill_weight > 0.0 {
        r = premultiplied(x, y);
    } else if L.from_acc != 0u {
        let q = (y * L.src_w + x) * PER_PIXEL;
        if acc[q + 3u] >= MIN_WEIGHT {
            for (var c = 0u; c < 5u; c++) {
                r[c] = acc[q + c];
            }
        }
    } else {
        let q = (L.src + y * L.src_w + x) * 5u;
        for (var c = 0u; c < 5u; c++) {
            r[c] = pyramid[q + c];
        }
    }
    return r;
}

// Block `i` of level `L.dst`: its children below summed in the order (0, 0), (1, 0),
// (0, 1), (1, 1) from zero, as the CPU adds them.
fn children(i: u32) -> array<f32, 5> {
    let bx = i % L.dst_w;
    let by = i / L.dst_w;
    var sum: array<f32, 5>;
    for (var k = 0u; k < 4u; k++) {
        let x = 2u * bx + (k & 1u);
        let y = 2u * by + (k >> 1u);
        if x < L.src_w && y < L.src_h {
            let s = below(x, y);
            for (var c = 0u; c < 5u; c++) {
                sum[c] += s[c];
            }
        }
    }
    return sum;
}

@compute @workgroup_size(256)
fn pull(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= L.dst_w * L.dst_h {
        return;
    }
    let sum = children(i);
    let q = (L.dst + i) * 5u;
    for (var c = 0u; c < 5u; c++) {
        pyramid[q + c] = sum[c];
    }
}

@compute @workgroup_size(256)
fn holes(@builtin(global_invocation_id) gid: vec3<u32>) {
    let pix = gid.x;
    if pix >= P.width * P.height || acc[pix * PER_PIXEL + 3u] >= MIN_WEIGHT {
        return;
    }
    let x = pix % P.width;
    let y = pix / P.width;
    var w = P.width;
    var h = P.height;
    var off = 0u;
    for (var k = 1u; k <= P.levels; k++) {
        let lw = (w + 1u) / 2u;
        let lh = (h + 1u) / 2u;
        let q = (off + (y >> k) * lw + (x >> k)) * 5u;
        let sw = pyramid[q + 3u];
        if sw > 0.0 {
            let inv = 1.0 / sw;
            let o = pix * PER_PIXEL;
            out[o] = pyramid[q] * inv;
            out[o + 1u] = pyramid[q + 1u] * inv;
            out[o + 2u] = pyramid[q + 2u] * inv;
            out[o + 3u] = pyramid[q + 4u] * inv;
            return;
        }
        off += lw * lh;
        w = lw;
        h = lh;
    }
}

// The pull-push fill of pixels whose weight is below `fill_weight` (the CPU's
// `pullpush.rs`): levels of premultiplied (red, green, blue, age, coverage α) in
// `pyramid`, pulled up as coverage-weighted 2×2 sums capped at coverage 1, pushed
// down as `own + (1 − α) · bilinear(coarser)`.

// The full-resolution level at pixel (x, y): α = min(W / W₀, 1); zero for a hole.
fn premultiplied(x: u32, y: u32) -> array<f32, 5> {
    let q = (y * P.width + x) * PER_PIXEL;
    var r: array<f32, 5>;
    let cw = acc[q + 3u];
    if cw >= MIN_WEIGHT {
        let a = min(cw / P.fill_weight, 1.0);
        for (var c = 0u; c < 4u; c++) {
            r[c] = out[q + c] * a;
        }
        r[4] = a;
    }
    return r;
}

// A pull-push level: the children's sums, scaled to coverage 1 where they exceed it.
@compute @workgroup_size(256)
fn pp_pull(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= L.dst_w * L.dst_h {
        return;
    }
    let sum = children(i);
    var k = 1.0;
    if sum[4] > 1.0 {
        k = 1.0 / sum[4];
    }
    let q = (L.dst + i) * 5u;
    for (var c = 0u; c < 5u; c++) {
        pyramid[q + c] = sum[c] * k;
    }
}

// The coarsest level (`L.dst`, one block) divided by its coverage.
@compute @workgroup_size(1)
fn pp_top() {
    let q = L.dst * 5u;
    let a = pyramid[q + 4u];
    if a > 0.0 {
        let k = 1.0 / a;
        for (var c = 0u; c < 5u; c++) {
            pyramid[q + c] *= k;
        }
    }
}

// The bilinear taps of pixel `i` of a level twice as fine as one of `n` pixels: the
// two coarse pixels around its centre (clamped at the edges) and the second's weight.
fn tap(i: u32, n: u32) -> vec3<f32> {
    let f = clamp((f32(i) + 0.5) * 0.5 - 0.5, 0.0, f32(n - 1u));
    let i0 = u32(f);
    return vec3<f32>(f32(i0), f32(min(i0 + 1u, n - 1u)), f - f32(i0));
}

// The coarser level `L.dst` interpolated at pixel (x, y) of the finer one: along x
// first, then along y, as the CPU does.
fn bilinear(x: u32, y: u32) -> array<f32, 4> {
    let tx = tap(x, L.dst_w);
    let ty = tap(y, L.dst_h);
    let x0 = u32(tx.x);
    let x1 = u32(tx.y);
    let r0 = L.dst + u32(ty.x) * L.dst_w;
    let r1 = L.dst + u32(ty.y) * L.dst_w;
    var v: array<f32, 4>;
    for (var c = 0u; c < 4u; c++) {
        let a0 = pyramid[(r0 + x0) * 5u + c];
        let b0 = pyramid[(r0 + x1) * 5u + c];
        let a1 = pyramid[(r1 + x0) * 5u + c];
        let b1 = pyramid[(r1 + x1) * 5u + c];
        let u0 = a0 + (b0 - a0) * tx.z;
        let u1 = a1 + (b1 - a1) * tx.z;
        v[c] = u0 + (u1 - u0) * ty.z;
    }
    return v;
}

// Push into pyramid level `L.src` from `L.dst`.
@compute @workgroup_size(256)
fn pp_push(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= L.src_w * L.src_h {
        return;
    }
    let up = bilinear(i % L.src_w, i / L.src_w);
    let q = (L.src + i) * 5u;
    let a = pyramid[q + 4u];
    for (var c = 0u; c < 4u; c++) {
        pyramid[q + c] += (1.0 - a) * up[c];
    }
    pyramid[q + 4u] = 1.0;
}

// Push into the image: only pixels below full coverage change.
@compute @workgroup_size(256)
fn pp_final(@builtin(global_invocation_id) gid: vec3<u32>) {
    let pix = gid.x;
    if pix >= P.width * P.height {
        return;
    }
    let x = pix % P.width;
    let y = pix / P.width;
    let v = premultiplied(x, y);
    let a = v[4];
    if a < 1.0 {
        let up = bilinear(x, y);
        let q = pix * PER_PIXEL;
        for (var c = 0u; c < 4u; c++) {
            out[q + c] = v[c] + (1.0 - a) * up[c];
        }
    }
}
