// The still-region history's refresh in compute shaders: the same steps and the same
// arithmetic as the CPU's, over per-pixel arrays that stay on the GPU. The CPU decides
// each refresh (the view change, which samples enter and where, in the order they
// came, and which pixels moving surfaces cut) and uploads that; these passes carry it
// out over the reconstruction in `image`, writing what is shown to `shown`.
//
// reset   one thread per pixel: every pixel's history empty (a new view, not followed).
// depth   one thread per pixel with history: where its surface point is seen now; the
//         nearest depth wins each destination pixel (atomic max of complemented bits).
// pick    the same, the lowest source pixel among those at the nearest depth (the CPU
//         visits pixels in order and keeps the first nearest).
// take    one thread per pixel: the winner's history, its count capped, into `scratch`.
// count   one thread per fresh sample (in the order they came): counted in its pixel's
//         16×16 bin.
// scan    one workgroup: each bin's first item (exclusive prefix sum of the counts).
// fill    one thread per fresh sample: its index into its bin.
// sort    one workgroup per bin: the bin's sample indices by pixel and, within a
//         pixel, in the order they came, whatever order the atomic counters handed
//         out the slots in (one thread for a bin of few, a bitonic network for more).
// fresh   one thread per run of fresh samples of a pixel: the samples in order; the
//         run's end offered as its block's newest (atomic max).
// refs    one thread per block of pixels: the colour of its newest fresh sample kept as
//         its reference.
// cut     one thread per pixel a moving surface covers now.
// blend   one thread per pixel: the clamp to the reconstruction's 3×3 box, the blend,
//         the colour shown at its block's reference where within roundings of it.

struct H {
    eye: vec3<f32>,
    t: f32,
    forward: vec3<f32>,
    n_fresh: u32,
    corner: vec3<f32>,
    n_cuts: u32,
    du: vec3<f32>,
    du2: f32,
    dv: vec3<f32>,
    dv2: f32,
    width: u32,
    height: u32,
    slack: f32,
    // `1 / (1 + depth tolerance)` of the visibility pass, 0 without it.
    keep: f32,
    recon_weight: f32,
    max_count: f32,
    box_scale: f32,
    tolerance: f32,
    clamped_count: f32,
    min_count_to_test: f32,
    reprojected_count: f32,
    // Bins of `BIN`×`BIN` pixels across the image.
    bins_x: u32,
}

// Floats per pixel of the history: mean colour (3), mean time, count, luminance range
// (2), newest hit point (3), padding (2).
const ACC: u32 = 12u;
const MEAN: u32 = 0u;
const TMEAN: u32 = 3u;
const COUNT: u32 = 4u;
const LO: u32 = 5u;
const HI: u32 = 6u;
const POINT: u32 = 7u;
// Floats per held sample: flag, colour (3), time, hit point (3). After the pixels'
// held samples, `held` keeps the reference colours of the blocks of `REF_BLOCK`² pixels
// (3 floats each, a row of blocks after another), and after the cut count `pick` has
// each block's newest fresh sample this refresh (its place in the order, plus one).
const HELD: u32 = 8u;
// `REF_BLOCK`, the side of a block, `REF_TOLERANCE`, how far from its block's
// reference (relative to it) a colour is shown as the reference, and `CLAMP_ROUNDING`,
// how far outside its box (in parts of the box's reach) a history's mean still counts
// as kept, are prepended by the Rust side.
// Floats per fresh sample: pixel (bits), still flag, colour (3), time, hit point (3),
// padding.
const FRESH: u32 = 10u;
// `IMAGE`, floats per pixel of the reconstruction and of what is shown (red, green,
// blue, age, coverage (bits), splat scale), and `BIN`, the side of a bin, are
// prepended by the Rust side.
const OUTSIDE: u32 = 0xffffffffu;

@group(0) @binding(0) var<uniform> P: H;
@group(0) @binding(1) var<storage, read_write> acc: array<f32>;
@group(0) @binding(2) var<storage, read_write> scratch: array<f32>;
@group(0) @binding(3) var<storage, read_write> held: array<f32>;
// Per pixel the nearest depth (complemented bits), then per pixel the winner
// (complemented index); then the count of pixels cut.
@group(0) @binding(4) var<storage, read_write> pick: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read> fresh: array<f32>;
@group(0) @binding(6) var<storage, read> cut_list: array<u32>;
@group(0) @binding(7) var<storage, read> image: array<f32>;
// The reconstruction's front depths, as the complement of their bits (0: none).
@group(0) @binding(8) var<storage, read> front: array<u32>;
@group(0) @binding(9) var<storage, read_write> shown: array<f32>;
@group(0) @binding(10) var<storage, read_write> counts: array<f32>;
// The fresh samples by bin: per bin their count, then a cursor, then (one more) where
// its items start; then the items, each a sample's index.
@group(0) @binding(11) var<storage, read_write> order: array<atomic<u32>>;

fn pixels() -> u32 {
    return P.width * P.height;
}

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
}

fn infinity() -> f32 {
    return bitcast<f32>(0x7f800000u);
}

// The pixel where world point `p` is seen now and the bits of its depth, or `OUTSIDE`.
fn pixel_at(p: vec3<f32>) -> vec2<u32> {
    let d = p - P.eye;
    let z = dot(d, P.forward);
    if !(z > 1e-6) {
        return vec2<u32>(OUTSIDE, 0u);
    }
    let q = d / z - P.corner;
    let x = dot(q, P.du) / P.du2;
    let y = dot(q, P.dv) / P.dv2;
    if !(x >= 0.0 && y >= 0.0 && x < f32(P.width) && y < f32(P.height)) {
        return vec2<u32>(OUTSIDE, 0u);
    }
    return vec2<u32>(u32(y) * P.width + u32(x), bitcast<u32>(z));
}

// Whether depth `z` lies behind the front depth of pixel `q` (beyond the tolerance).
fn hidden(q: u32, z: f32) -> bool {
    let f = front[q];
    return P.keep > 0.0 && f != 0u && bitcast<f32>(~f) < z * P.keep;
}

fn vec_at(a: u32) -> vec3<f32> {
    return vec3<f32>(acc[a], acc[a + 1u], acc[a + 2u]);
}

fn set_vec(a: u32, v: vec3<f32>) {
    acc[a] = v.x;
    acc[a + 1u] = v.y;
    acc[a + 2u] = v.z;
}

fn clear_acc(q: u32) {
    let a = q * ACC;
    set_vec(a + MEAN, vec3<f32>(0.0));
    acc[a + TMEAN] = 0.0;
    acc[a + COUNT] = 0.0;
    acc[a + LO] = infinity();
    acc[a + HI] = -infinity();
}

fn cut(q: u32) {
    if acc[q * ACC + COUNT] > 0.0 {
        atomicAdd(&pick[2u * pixels()], 1u);
    }
    clear_acc(q);
    held[q * HELD] = 0.0;
}

fn add(q: u32, c: vec3<f32>, t: f32, hit: vec3<f32>) {
    let a = q * ACC;
    set_vec(a + POINT, hit);
    let n0 = acc[a + COUNT];
    var n = n0 + 1.0;
    // A running mean: exactly `c` while every sample is `c`.
    let m = vec_at(a + MEAN);
    let mean = select(c, m + (c - m) / n, n0 > 0.0);
    // The mean time, not the sum: f32 keeps it to rounding over any count.
    acc[a + TMEAN] += (t - acc[a + TMEAN]) / n;
    let l = luminance(c);
    acc[a + LO] = min(acc[a + LO], l);
    acc[a + HI] = max(acc[a + HI], l);
    n = min(n, P.max_count);
    set_vec(a + MEAN, mean);
    acc[a + COUNT] = n;
}

@compute @workgroup_size(256)
fn reset(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if q >= pixels() {
        return;
    }
    clear_acc(q);
    held[q * HELD] = 0.0;
}

// Where pixel `q`'s history is seen now, unless it has none or lies hidden.
fn destination(q: u32) -> vec2<u32> {
    if !(acc[q * ACC + COUNT] > 0.0) {
        return vec2<u32>(OUTSIDE, 0u);
    }
    let r = pixel_at(vec_at(q * ACC + POINT));
    if r.x == OUTSIDE || hidden(r.x, bitcast<f32>(r.y)) {
        return vec2<u32>(OUTSIDE, 0u);
    }
    return r;
}

@compute @workgroup_size(256)
fn depth(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if q >= pixels() {
        return;
    }
    let r = destination(q);
    if r.x != OUTSIDE {
        atomicMax(&pick[r.x], ~r.y);
    }
}

@compute @workgroup_size(256)
fn pick_winner(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if q >= pixels() {
        return;
    }
    let r = destination(q);
    if r.x != OUTSIDE && atomicLoad(&pick[r.x]) == ~r.y {
        atomicMax(&pick[pixels() + r.x], ~q);
    }
}

@compute @workgroup_size(256)
fn take(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = gid.x;
    if d >= pixels() {
        return;
    }
    held[d * HELD] = 0.0;
    let w = atomicLoad(&pick[pixels() + d]);
    let b = d * ACC;
    if w == 0u {
        for (var k = 0u; k < 5u; k++) {
            scratch[b + k] = 0.0;
        }
        scratch[b + LO] = infinity();
        scratch[b + HI] = -infinity();
        return;
    }
    let a = (~w) * ACC;
    let n = acc[a + COUNT];
    let k = min(n, P.reprojected_count) / n;
    for (var i = 0u; i < 3u; i++) {
        scratch[b + MEAN + i] = acc[a + MEAN + i];
    }
    scratch[b + TMEAN] = acc[a + TMEAN];
    scratch[b + COUNT] = n * k;
    for (var i = LO; i < ACC; i++) {
        scratch[b + i] = acc[a + i];
    }
}

fn fresh_pixel(i: u32) -> u32 {
    return bitcast<u32>(fresh[i * FRESH]);
}

// Fresh sample `i` in pixel `q`: a moving one cuts it; a still one joins it if it
// agrees with what the pixel showed, is held back if not, and starts the pixel over
// with the held one if it is the second in a row that does not.
fn take_in(q: u32, i: u32) {
    let f = i * FRESH;
    if fresh[f + 1u] == 0.0 {
        cut(q);
        return;
    }
    let c = vec3<f32>(fresh[f + 2u], fresh[f + 3u], fresh[f + 4u]);
    let t = fresh[f + 5u];
    let hit = vec3<f32>(fresh[f + 6u], fresh[f + 7u], fresh[f + 8u]);
    let a = q * ACC;
    let l = luminance(c);
    let outside = acc[a + COUNT] >= P.min_count_to_test
        && (l < acc[a + LO] - P.slack || l > acc[a + HI] + P.slack);
    let h = q * HELD;
    let was_held = held[h] != 0.0;
    held[h] = 0.0;
    let hc = vec3<f32>(held[h + 1u], held[h + 2u], held[h + 3u]);
    let ht = held[h + 4u];
    let hhit = vec3<f32>(held[h + 5u], held[h + 6u], held[h + 7u]);
    if !outside {
        if was_held {
            add(q, hc, ht, hhit);
        }
        add(q, c, t, hit);
    } else if !was_held {
        held[h] = 1.0;
        held[h + 1u] = c.x;
        held[h + 2u] = c.y;
        held[h + 3u] = c.z;
        held[h + 4u] = t;
        held[h + 5u] = hit.x;
        held[h + 6u] = hit.y;
        held[h + 7u] = hit.z;
    } else {
        cut(q);
        add(q, hc, ht, hhit);
        add(q, c, t, hit);
    }
}

fn bin_count() -> u32 {
    return P.bins_x * ((P.height + BIN - 1u) / BIN);
}

fn bin_of(q: u32) -> u32 {
    return (q / P.width) / BIN * P.bins_x + (q % P.width) / BIN;
}

// Where bin `b`'s first item is in `order`, once scanned (`b` up to the bin count).
fn bin_start(b: u32) -> u32 {
    return 3u * bin_count() + 1u + atomicLoad(&order[2u * bin_count() + b]);
}

@compute @workgroup_size(256)
fn count_fresh(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x < P.n_fresh {
        atomicAdd(&order[bin_of(fresh_pixel(gid.x))], 1u);
    }
}

var<workgroup> partial: array<u32, 256>;

@compute @workgroup_size(256)
fn scan_fresh(@builtin(local_invocation_index) li: u32) {
    let nb = bin_count();
    let per = (nb + 255u) / 256u;
    let b0 = min(li * per, nb);
    let b1 = min(b0 + per, nb);
    var sum = 0u;
    for (var b = b0; b < b1; b++) {
        sum += atomicLoad(&order[b]);
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
        atomicStore(&order[2u * nb + b], run);
        run += atomicLoad(&order[b]);
        atomicStore(&order[nb + b], 0u);
    }
    if li == 255u {
        atomicStore(&order[3u * nb], partial[255]);
    }
}

@compute @workgroup_size(256)
fn fill_fresh(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= P.n_fresh {
        return;
    }
    let b = bin_of(fresh_pixel(i));
    let slot = bin_start(b) + atomicAdd(&order[bin_count() + b], 1u);
    atomicStore(&order[slot], i);
}

var<workgroup> sort_n: u32;
var<workgroup> sort_o: u32;

// A bitonic network whose comparators all put the smaller index first (the first
// step of each merge compares mirrored positions), so the list need not be a power
// of two long: positions past its end act as +∞ and are never moved into it.
@compute @workgroup_size(256)
fn sort_fresh(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if li == 0u {
        let b = wid.y * P.bins_x + wid.x;
        sort_o = bin_start(b);
        sort_n = bin_start(b + 1u) - sort_o;
    }
    let n = workgroupUniformLoad(&sort_n);
    let o = workgroupUniformLoad(&sort_o);
    if n <= SMALL_BIN {
        // Most bins hold a few samples: one thread sorts them, without the network's
        // barriers (each a pause of the whole workgroup).
        if li == 0u {
            insertion_sort(o, n);
        }
        return;
    }
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
                    let a = atomicLoad(&order[o + i]);
                    let b = atomicLoad(&order[o + q]);
                    if before(b, a) {
                        atomicStore(&order[o + i], b);
                        atomicStore(&order[o + q], a);
                    }
                }
            }
            storageBarrier();
            workgroupBarrier();
        }
    }
}

// Bins of at most this many samples are sorted by one thread.
const SMALL_BIN: u32 = 32u;

// Whether fresh sample `a` goes before `b`: in a lower pixel, or in the same one
// and earlier.
fn before(a: u32, b: u32) -> bool {
    let pa = fresh_pixel(a);
    let pb = fresh_pixel(b);
    return pa < pb || (pa == pb && a < b);
}

// The `n` indices from `order[o]` sorted by `before`.
fn insertion_sort(o: u32, n: u32) {
    for (var i = 1u; i < n; i++) {
        let v = atomicLoad(&order[o + i]);
        var j = i;
        while j > 0u && before(v, atomicLoad(&order[o + j - 1u])) {
            atomicStore(&order[o + j], atomicLoad(&order[o + j - 1u]));
            j--;
        }
        atomicStore(&order[o + j], v);
    }
}

// The fresh sample at position `k` of the sorted items.
fn sorted_at(k: u32) -> u32 {
    return atomicLoad(&order[3u * bin_count() + 1u + k]);
}

@compute @workgroup_size(256)
fn take_fresh(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.x;
    if k >= P.n_fresh {
        return;
    }
    let q = fresh_pixel(sorted_at(k));
    // Bins are listed in order and sorted by pixel within: a pixel's samples are one
    // run, taken in by the thread at its start.
    if k > 0u && fresh_pixel(sorted_at(k - 1u)) == q {
        return;
    }
    var j = k;
    for (; j < P.n_fresh && fresh_pixel(sorted_at(j)) == q; j++) {
        take_in(q, sorted_at(j));
    }
    // A block lies in one bin, sorted by pixel: its last item is the sample the CPU
    // takes in last of the block.
    atomicMax(&pick[2u * pixels() + 1u + block_of(q)], j);
}

fn blocks_across() -> u32 {
    return (P.width + REF_BLOCK - 1u) / REF_BLOCK;
}

fn block_count() -> u32 {
    return blocks_across() * ((P.height + REF_BLOCK - 1u) / REF_BLOCK);
}

fn block_of(q: u32) -> u32 {
    return (q / P.width) / REF_BLOCK * blocks_across() + (q % P.width) / REF_BLOCK;
}

// Where block `b`'s reference colour is in `held`.
fn ref_at(b: u32) -> u32 {
    return pixels() * HELD + 3u * b;
}

fn block_ref(x: u32, y: u32) -> vec3<f32> {
    let h = ref_at(y / REF_BLOCK * blocks_across() + x / REF_BLOCK);
    return vec3<f32>(held[h], held[h + 1u], held[h + 2u]);
}

@compute @workgroup_size(256)
fn refs(@builtin(global_invocation_id) gid: vec3<u32>) {
    let b = gid.x;
    if b >= block_count() {
        return;
    }
    let last = atomicLoad(&pick[2u * pixels() + 1u + b]);
    if last == 0u {
        return;
    }
    let f = sorted_at(last - 1u) * FRESH;
    let h = ref_at(b);
    held[h] = fresh[f + 2u];
    held[h + 1u] = fresh[f + 3u];
    held[h + 2u] = fresh[f + 4u];
}

@compute @workgroup_size(256)
fn cut_moving(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i < P.n_cuts {
        cut(cut_list[i]);
    }
}

fn image_rgb(q: u32) -> vec3<f32> {
    return vec3<f32>(image[q * IMAGE], image[q * IMAGE + 1u], image[q * IMAGE + 2u]);
}

@compute @workgroup_size(256)
fn blend(@builtin(global_invocation_id) gid: vec3<u32>) {
    let q = gid.x;
    if q >= pixels() {
        return;
    }
    let x = q % P.width;
    let y = q / P.width;
    var lo = image_rgb(q);
    var hi = lo;
    for (var yy = max(y, 1u) - 1u; yy <= min(y + 1u, P.height - 1u); yy++) {
        for (var xx = max(x, 1u) - 1u; xx <= min(x + 1u, P.width - 1u); xx++) {
            let c = image_rgb(yy * P.width + xx);
            lo = min(lo, c);
            hi = max(hi, c);
        }
    }
    let o = q * IMAGE;
    var rgb = image_rgb(q);
    var age = image[o + 3u];
    let a = q * ACC;
    var n = acc[a + COUNT];
    if n > 0.0 {
        let mid = (lo + hi) * 0.5;
        let slack = (hi - lo) * (0.5 * P.box_scale) + vec3<f32>(P.tolerance);
        let mean = vec_at(a + MEAN);
        let clamped = min(max(mean, mid - slack), mid + slack);
        // Kept within roundings of its box (`CLAMP_ROUNDING` of its reach).
        if !all(abs(clamped - mean) <= slack * CLAMP_ROUNDING) {
            // The reconstruction disagrees: new samples take over.
            n = min(n, P.clamped_count);
            atomicAdd(&pick[2u * pixels()], 1u);
            acc[a + COUNT] = n;
            set_vec(a + MEAN, clamped);
            let l = luminance(clamped);
            acc[a + LO] = select(infinity(), l, n > 0.0);
            acc[a + HI] = select(-infinity(), l, n > 0.0);
        }
        let k = P.recon_weight;
        // The mean moved towards the reconstruction: a converged mean is shown as it
        // is where the reconstruction differs from it by roundings.
        rgb = clamped + (rgb - clamped) * (k / (k + n));
        let hist_age = select(0.0, P.t - acc[a + TMEAN], n > 0.0);
        age = (age * k + hist_age * n) / (k + n);
    }
    let r = block_ref(x, y);
    // Not to an infinite reference: every value is within an infinite tolerance.
    let within = abs(r) * REF_TOLERANCE;
    rgb = select(rgb, r, abs(rgb - r) <= within & within <= vec3<f32>(3.4e38));
    shown[o] = rgb.x;
    shown[o + 1u] = rgb.y;
    shown[o + 2u] = rgb.z;
    shown[o + 3u] = age;
    shown[o + 4u] = image[o + 4u];
    shown[o + 5u] = image[o + 5u];
    counts[q] = n;
}
