//! The Rust side of the shaders' interface checked against the WGSL, without a GPU:
//! naga (which wgpu already brings) parses the shaders on the CPU, and each uniform or
//! storage struct the Rust side uploads must have the WGSL struct's fields, in its
//! order, at its offsets, with its sizes; the constants both sides use must agree. A
//! field reordered, added or resized on one side only fails here instead of in the
//! `gpu_` tests, which need an adapter and are ignored by default.

use naga::{Expression, Literal, Module, TypeInner};

use super::{field, recon_source, GpuTile, Level, Params, RING_FIELDS, SPLAT_BYTES};

/// A struct's fields as `(name, offset, size)`, bytes; padding fields (`pad…`) left out
/// (their names differ: one array on the Rust side, scalars in WGSL), so only the total
/// size speaks for them.
pub(super) type Fields = Vec<(String, usize, usize)>;

/// The Rust struct `$t`'s fields `$f…`, as [`Fields`].
macro_rules! rust_fields {
    ($t:ty { $($f:ident),* $(,)? }) => {{
        fn size_of_field<T, F>(_: fn(&T) -> &F) -> usize {
            std::mem::size_of::<F>()
        }
        let fields: crate::reconstruction::gpu::layout_tests::Fields = vec![$((
            stringify!($f).to_string(),
            std::mem::offset_of!($t, $f),
            size_of_field(|s: &$t| &s.$f),
        )),*];
        fields
    }};
}
pub(super) use rust_fields;

/// Parse a shader as wgpu would.
pub(super) fn parse(source: &str) -> Module {
    naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)))
}

/// The WGSL struct `name`'s fields, as [`Fields`], and its size.
pub(super) fn wgsl_fields(module: &Module, name: &str) -> (Fields, usize) {
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the shader"))
        .1;
    let TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{name} is not a struct");
    };
    let fields = members
        .iter()
        .map(|m| {
            let size = module.types[m.ty].inner.size(module.to_ctx()) as usize;
            (m.name.clone().unwrap_or_default(), m.offset as usize, size)
        })
        .filter(|(n, _, _)| !n.starts_with("pad"))
        .collect();
    (fields, *span as usize)
}

/// Check that the Rust struct of `rust` fields and `rust_size` bytes lays out as the
/// WGSL struct `name` of `module`.
pub(super) fn check_struct(module: &Module, name: &str, rust: Fields, rust_size: usize) {
    let rust: Fields = rust
        .into_iter()
        .filter(|(n, _, _)| !n.starts_with("pad"))
        .collect();
    let (wgsl, wgsl_size) = wgsl_fields(module, name);
    assert_eq!(
        rust, wgsl,
        "struct {name}: the Rust fields (left) are not the WGSL's (right), as (name, offset, size)"
    );
    assert_eq!(
        rust_size, wgsl_size,
        "struct {name}: Rust and WGSL sizes differ"
    );
}

/// The value of the WGSL constant `name`, an unsigned integer.
pub(super) fn wgsl_u32(module: &Module, name: &str) -> u32 {
    let c = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no constant {name} in the shader"))
        .1;
    match module.global_expressions[c.init] {
        Expression::Literal(Literal::U32(v)) => v,
        ref e => panic!("constant {name} is {e:?}, not a u32 literal"),
    }
}

#[test]
fn recon_wgsl_lays_out_the_structs_as_the_rust_side() {
    let m = parse(&recon_source());
    let params = rust_fields!(Params {
        eye,
        t,
        forward,
        reproject,
        u,
        ou,
        v,
        ov,
        width,
        height,
        cap,
        first,
        count,
        bins_x,
        bins_y,
        items_cap,
        temporal_cutoff,
        max_r,
        grow,
        shrink,
        undersampled,
        oversampled,
        scale_lo,
        scale_hi,
        levels,
        keep,
        setter_age,
        fill_weight,
        carry,
        tiles,
        spread,
        track,
        parallax,
        footprint,
        footprint_parallax,
        footprint_reach,
        t_newest,
        pad,
    });
    check_struct(&m, "Params", params, std::mem::size_of::<Params>());
    let tile = rust_fields!(GpuTile {
        inv_et,
        ax,
        ay,
        cx,
        cy,
        x0,
        y0,
        x1,
        y1,
        pad
    });
    check_struct(&m, "TileFilter", tile, std::mem::size_of::<GpuTile>());
    let level = rust_fields!(Level {
        src,
        dst,
        src_w,
        src_h,
        dst_w,
        dst_h,
        from_acc,
        pad
    });
    check_struct(&m, "Level", level, std::mem::size_of::<Level>());
    // The splats live on the GPU alone: only their size is the Rust side's.
    let (_, splat) = wgsl_fields(&m, "Splat");
    assert_eq!(
        splat as u64, SPLAT_BYTES,
        "SPLAT_BYTES is not the WGSL Splat's size"
    );
}

#[test]
fn recon_wgsl_reads_the_ring_fields_where_the_rust_side_writes_them() {
    let m = parse(&recon_source());
    for (name, index) in [
        ("X", field::X),
        ("Y", field::Y),
        ("R", field::R),
        ("HX", field::HX),
        ("VX", field::VX),
        ("T", field::COUNT),
    ] {
        assert_eq!(wgsl_u32(&m, name) as usize, index, "ring field {name}");
    }
    assert_eq!(RING_FIELDS, field::COUNT + 1);
}
