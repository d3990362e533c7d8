// What is shown, from the per-pixel runs the passes write (red, green, blue, age,
// coverage bits, splat scale: `PER_PIXEL` floats, prepended by the Rust side) into
// the read-back's planes: red, green and blue a pixel after another (as the CPU
// image holds them), then every age, every coverage, every splat scale. The CPU then
// copies each plane whole instead of picking the floats apart.

@group(0) @binding(0) var<storage, read> src: array<f32>;
@group(0) @binding(1) var<storage, read_write> dst: array<f32>;

@compute @workgroup_size(256)
fn pack(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = arrayLength(&dst) / PER_PIXEL;
    let q = gid.x;
    if q >= n {
        return;
    }
    let s = q * PER_PIXEL;
    dst[3u * q] = src[s];
    dst[3u * q + 1u] = src[s + 1u];
    dst[3u * q + 2u] = src[s + 2u];
    dst[3u * n + q] = src[s + 3u];
    dst[4u * n + q] = src[s + 4u];
    dst[5u * n + q] = src[s + 5u];
}
