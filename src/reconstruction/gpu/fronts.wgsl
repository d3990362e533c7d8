// The initial front depths a carrying refresh with the visibility pass starts from,
// kept between refreshes (`kept`, as the shaders store fronts: the complement of a
// depth's bits, 0 for none): the CPU lists the pixels whose front changed since the
// last refresh, and `scatter_fronts` writes them, one thread per pixel listed. The
// refresh then copies `kept` into its front depths, which its new samples lower.

struct FrontParams {
    // Pixels listed, and pixels of the image.
    count: u32,
    pixels: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> F: FrontParams;
// Per pixel listed: the pixel and its front's bits.
@group(0) @binding(1) var<storage, read> changes: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read_write> kept: array<u32>;

@compute @workgroup_size(256)
fn scatter_fronts(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= F.count {
        return;
    }
    let c = changes[gid.x];
    if c.x < F.pixels {
        kept[c.x] = c.y;
    }
}
