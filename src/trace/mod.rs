//! The ray tracer: scene state at a time, sample queries, Whitted shading.
//!
//! A [`Tracer`] is built once per scene and image size. Scene state (rigid instance
//! transforms, animated triangle positions, lights, camera) is evaluated per
//! [`SceneState`]; states are quantized to [`TIME_QUANTUM`] (1 ms) and cached, so a
//! stream of samples at ever-increasing times rebuilds the small dynamic parts at most a
//! thousand times per simulated second, never the static world.

pub mod accel;
pub mod batch;
mod build;
pub mod cones;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod intersect;
mod shade;

pub use cones::TextureFilter;

use std::sync::{
    atomic::{AtomicU64, Ordering},
    Arc, Mutex, RwLock,
};

use glam::{Mat3, Mat4, Vec2, Vec3, Vec3A};
use obvhs::{
    aabb::Aabb,
    bvh2::Bvh2,
    ray::{Ray, RayHit},
    rt_triangle::RtTriangle,
    triangle::Triangle as ObTriangle,
};

use crate::scene::{Camera, CameraFrame, CameraPath, MaterialId, Scene, Triangle};
use accel::{build_top_level, transform_aabb, Analytic, GroupAccel, InstanceState, PrimRef};
use cones::{Footprint, RayCone};

/// Version of what the tracer returns for given options. Bump whenever a change makes
/// the tracer's output differ for some scene, time and options (shading, intersection,
/// texture lookups), so that images cached under the old version are not reused.
/// 2: BVHs built top-down by binned SAH (which of two coincident triangles is hit can
/// differ: 37 of 27,648 kitchen pixels at 192×144).
pub const RENDERER_VERSION: u32 = 2;

/// Scene state is evaluated at multiples of this many seconds (1 ms).
pub const TIME_QUANTUM: f64 = 1e-3;

/// Rec. 709 luminance of a linear RGB color.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// What a hit point is fixed to, so that where it is at another time can be evaluated
/// exactly ([`SceneState::anchor_position`]) instead of extrapolated by its velocity.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Anchor {
    /// The static world (or nothing hit): the point never moves.
    #[default]
    Still,
    /// A point of a rigid instance: the instance group and the point in its local space.
    Instance {
        /// Index of the instance group.
        group: u32,
        /// The point in the group's local space.
        local: Vec3,
    },
    /// A point of an animated (morphing) triangle: its index and barycentrics.
    Triangle {
        /// Index of the triangle in the animated triangles' acceleration structure.
        index: u32,
        /// Barycentric weights of the second and third vertices.
        u: f32,
        /// See `u`.
        v: f32,
    },
}

/// Everything a sample returns.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Linear RGB radiance.
    pub color: Vec3,
    /// Luminance of `color`.
    pub luminance: f32,
    /// World-space hit point (the ray's far point when nothing was hit).
    pub hit_point: Vec3,
    /// Distance from the eye to the hit point along the ray (`INFINITY` on a miss).
    pub depth: f32,
    /// World-space velocity of the hit point at the sample's time (zero if static).
    pub velocity: Vec3,
    /// Whether the primary ray hit anything.
    pub hit: bool,
    /// Whether something moving at the sample's time took part in it: its primary hit,
    /// a surface seen in a reflection or through a refraction, or a shadow caster or
    /// transmitter. A sample without it would look the same a moment later at the
    /// same place under the same camera (unless a light moves), so a still region's
    /// history may keep it.
    pub dynamic: bool,
    /// What the hit point is fixed to.
    pub anchor: Anchor,
}

/// A traced sample with where and when it was traced: what samplers stream to a
/// reconstructor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamSample {
    /// Sub-pixel position where it was traced.
    pub x: f32,
    /// Sub-pixel position where it was traced.
    pub y: f32,
    /// Time it was traced.
    pub t: f64,
    /// Everything the tracer returned.
    pub sample: Sample,
}

/// The scene state of the latest instant asked for, for one caller that asks about the
/// same instant many times in a row: the tracer's shared cache takes a lock, this does
/// not. Rebuilt when the 1 ms quantum or the live camera changes.
pub struct StateCache {
    key: StateKey,
    state: Option<Arc<SceneState>>,
}

impl Default for StateCache {
    fn default() -> Self {
        Self::new()
    }
}

impl StateCache {
    /// Empty.
    pub fn new() -> Self {
        Self {
            key: (i64::MIN, u64::MAX, i64::MIN),
            state: None,
        }
    }

    /// The state at `t`, and whether it replaced the one held before.
    pub fn at(&mut self, tracer: &Tracer, t: f64) -> (Arc<SceneState>, Held) {
        self.at_ahead(tracer, t, 0.0)
    }

    /// [`StateCache::at`] with the camera extrapolated `ahead` seconds
    /// ([`Tracer::state_at_ahead`]).
    pub fn at_ahead(&mut self, tracer: &Tracer, t: f64, ahead: f64) -> (Arc<SceneState>, Held) {
        let key = (
            Tracer::quantize(t),
            tracer.camera_generation(),
            Tracer::quantize(ahead),
        );
        match &self.state {
            Some(s) if key == self.key => (s.clone(), Held::Same),
            _ => {
                let s = tracer.state_at_ahead(t, ahead);
                self.key = key;
                let previous = self.state.replace(s.clone());
                (s, Held::New { previous })
            }
        }
    }
}

/// What [`StateCache::at`] did.
pub enum Held {
    /// It returned the state it held.
    Same,
    /// It built a new state, replacing `previous` (if it held one).
    New {
        /// The state held before.
        previous: Option<Arc<SceneState>>,
    },
}

/// Tracer settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceOptions {
    /// Maximum number of reflection/refraction bounces after the primary hit.
    pub max_depth: u32,
    /// Texture filtering ([`TextureFilter::default`], ray cones, unless asked for:
    /// every command traces with the same filter unless told otherwise).
    pub texture_filter: TextureFilter,
}

impl Default for TraceOptions {
    fn default() -> Self {
        Self {
            max_depth: crate::settings::MAX_DEPTH,
            texture_filter: TextureFilter::default(),
        }
    }
}

impl From<&crate::settings::QualityGroup> for TraceOptions {
    /// The tracer's settings of a run's quality group.
    fn from(q: &crate::settings::QualityGroup) -> Self {
        Self {
            max_depth: q.max_depth,
            texture_filter: q.texture_filter,
        }
    }
}

/// Animated triangles at one time: positions, normals and velocities in world space.
struct AnimState {
    bvh: Bvh2,
    tris: Vec<RtTriangle>,
    normals: Vec<[Vec3; 3]>,
    velocities: Vec<[Vec3; 3]>,
}

/// The dynamic part of the scene at one (quantized) time.
pub struct SceneState {
    /// The time this state represents, seconds.
    pub time: f64,
    /// The camera fixed to the tracer's image size.
    pub camera: CameraFrame,
    /// Lights: `(position, color)`.
    pub lights: Vec<(Vec3, Vec3)>,
    instances: Vec<InstanceState>,
    /// The index in `instances` of each instance group's instance (`u32::MAX`: not in
    /// the scene at this time).
    instance_of_group: Vec<u32>,
    top: Option<Bvh2>,
    anim: Option<AnimState>,
}

impl SceneState {
    /// Where the point `anchor` names is at this state's time (`None`: its instance is
    /// not in the scene now).
    pub fn anchor_position(&self, anchor: &Anchor) -> Option<Vec3> {
        match *anchor {
            Anchor::Still => None,
            Anchor::Instance { group, local } => {
                let i = *self.instance_of_group.get(group as usize)?;
                let inst = self.instances.get(i as usize)?;
                Some(inst.world.transform_point3(local))
            }
            Anchor::Triangle { index, u, v } => {
                let tri = self.anim.as_ref()?.tris.get(index as usize)?;
                // `v0·(1 − u − v) + v1·u + v2·v` with `e1 = v0 − v1`, `e2 = v2 − v0`.
                Some(Vec3::from(tri.v0 - tri.e1 * u + tri.e2 * v))
            }
        }
    }
}

/// Set in [`HitId`]'s primitive numbers for an analytic primitive (sphere, cone side);
/// clear for a triangle.
pub const ANALYTIC_BIT: u32 = 1 << 31;

/// Which primitive a ray hit, named alike by the CPU and the GPU tracer: a triangle by
/// its slot in its group's BVH order, an analytic primitive by its slot with
/// [`ANALYTIC_BIT`] set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HitId {
    /// Nothing.
    Miss,
    /// A primitive of the static world.
    Static(u32),
    /// A primitive of a rigid instance group.
    Instance {
        /// The group, as the tracer numbers its instance groups.
        group: u32,
        /// The primitive in the group.
        primitive: u32,
    },
    /// A morphing triangle, by its slot in their BVH.
    Morphing(u32),
}

impl HitId {
    /// From the GPU tracer's words: kind (0 miss, 1 static, 2 instance, 3 morphing),
    /// group, primitive.
    pub fn from_parts(kind: u32, group: u32, primitive: u32) -> Self {
        match kind {
            1 => Self::Static(primitive),
            2 => Self::Instance { group, primitive },
            3 => Self::Morphing(primitive),
            _ => Self::Miss,
        }
    }

    fn of(state: &SceneState, hit: Option<&Hit>) -> Self {
        let number = |p: PrimRef| match p {
            PrimRef::Tri(i) => i,
            PrimRef::Analytic(i) => ANALYTIC_BIT | i,
        };
        match hit.map(|h| h.at) {
            None => Self::Miss,
            Some(HitWhere::Static(p)) => Self::Static(number(p)),
            Some(HitWhere::Instance(i, p)) => Self::Instance {
                group: state.instances[i as usize].group,
                primitive: number(p),
            },
            Some(HitWhere::Anim(i)) => Self::Morphing(i),
        }
    }
}

/// Where a ray hit.
#[derive(Clone, Copy, Debug)]
enum HitWhere {
    Static(PrimRef),
    Instance(u32, PrimRef),
    Anim(u32),
}

#[derive(Clone, Copy, Debug)]
struct Hit {
    t: f32,
    at: HitWhere,
}

/// Local geometry at a hit, in world space.
pub(crate) struct Surface {
    pub p: Vec3,
    pub ng: Vec3,
    pub n: Vec3,
    pub uv: Vec2,
    pub material: MaterialId,
    pub velocity: Vec3,
    pub anchor: Anchor,
}

/// A ray tracer for one scene and one image size.
pub struct Tracer {
    scene: Arc<Scene>,
    options: TraceOptions,
    width: u32,
    height: u32,
    camera_path: Option<CameraPath>,
    static_geo: GroupAccel,
    instance_groups: Vec<(u32, GroupAccel)>,
    anim_base: Option<Bvh2>,
    scene_scale: f32,
    /// Cached states keyed by (time quantum, camera generation, quanta the camera is
    /// extrapolated ahead).
    cache: Mutex<Vec<(StateKey, Arc<SceneState>)>>,
    /// A live camera that overrides path and scene (the interactive viewer), with the
    /// generation it was set in. A state built under one generation is never served
    /// under another, so a state built concurrently with a camera change cannot leak
    /// the old view into the cache.
    live_camera: RwLock<(u64, Option<Camera>)>,
    camera_generation: AtomicU64,
}

const CACHE_STATES: usize = 8;

/// What a cached state is for: its time quantum, the camera generation, and the quanta
/// its camera is extrapolated ahead.
type StateKey = (i64, u64, i64);

/// The camera as far past `now` as `now` is past `before`, on the line through both.
fn extrapolated(before: Camera, now: Camera) -> Camera {
    Camera {
        eye: 2.0 * now.eye - before.eye,
        at: 2.0 * now.at - before.at,
        up: (2.0 * now.up - before.up).normalize_or(now.up),
        ..now
    }
}

/// `triangles` moved to world space by the static transform `m`.
fn baked_triangles(m: Mat4, triangles: &[Triangle]) -> impl Iterator<Item = Triangle> + '_ {
    let nm = Mat3::from_mat4(m).inverse().transpose();
    triangles.iter().map(move |t| Triangle {
        p: t.p.map(|p| m.transform_point3(p)),
        n: t.n.map(|n| n.map(|v| (nm * v).normalize_or(Vec3::Y))),
        ..*t
    })
}

/// Analytic shapes under a static node moved by its transform `m`: what is exact for
/// similarity transforms is baked.
fn baked_analytic(m: Mat4, analytic: Vec<Analytic>) -> impl Iterator<Item = Analytic> {
    let s = Mat3::from_mat4(m).to_cols_array();
    let scale = Vec3::new(s[0], s[1], s[2]).length();
    analytic.into_iter().map(move |a| match a {
        Analytic::Sphere(mut sp) => {
            sp.center = m.transform_point3(sp.center);
            sp.radius *= scale;
            Analytic::Sphere(sp)
        }
        Analytic::Cone(mut c) => {
            c.base = m.transform_point3(c.base);
            c.apex = m.transform_point3(c.apex);
            c.base_radius *= scale;
            c.apex_radius *= scale;
            Analytic::Cone(c)
        }
    })
}

impl Tracer {
    /// Build acceleration structures for `scene`, rendering `width × height` images.
    pub fn new(scene: Arc<Scene>, width: u32, height: u32, options: TraceOptions) -> Self {
        // Groups under no animated node join the static world, baked to world space.
        let mut static_tris: Vec<Triangle> = Vec::new();
        let mut static_analytic: Vec<Analytic> = Vec::new();
        let mut instance_groups = Vec::new();
        for g in &scene.groups {
            let analytic: Vec<Analytic> = g
                .spheres
                .iter()
                .map(|s| Analytic::Sphere(*s))
                .chain(g.cones.iter().map(|c| Analytic::Cone(*c)))
                .collect();
            match g.node {
                Some(node) if scene.node_is_animated(node) => {
                    instance_groups.push((node, GroupAccel::build(&g.triangles, analytic)));
                }
                node => {
                    let m = node.map_or(Mat4::IDENTITY, |n| scene.node_world(n, 0.0));
                    if m == Mat4::IDENTITY {
                        static_tris.extend_from_slice(&g.triangles);
                        static_analytic.extend(analytic);
                    } else {
                        static_tris.extend(baked_triangles(m, &g.triangles));
                        static_analytic.extend(baked_analytic(m, analytic));
                    }
                }
            }
        }
        let static_geo = GroupAccel::build(&static_tris, static_analytic);
        let anim_base = if scene.animated_triangles.is_empty() {
            None
        } else {
            let tris = anim_positions(&scene, scene.time_range().0 as f64);
            let boxes: Vec<Aabb> = tris.iter().map(|(t, _, _)| t.aabb()).collect();
            // One triangle per leaf keeps refitting a plain per-node update.
            Some(build::build_bvh2(&boxes))
        };
        let mut bounds = static_geo.aabb;
        for (_, g) in &instance_groups {
            bounds = bounds.union(&g.aabb);
        }
        let d = bounds.diagonal();
        let scene_scale = if d.is_finite() {
            d.max_element().max(1e-3)
        } else {
            1.0
        };
        Self {
            scene,
            options,
            width: width.max(1),
            height: height.max(1),
            camera_path: None,
            static_geo,
            instance_groups,
            anim_base,
            scene_scale,
            cache: Mutex::new(Vec::new()),
            live_camera: RwLock::new((0, None)),
            camera_generation: AtomicU64::new(0),
        }
    }

    /// Override the camera of every state built from now on (`None`: back to the
    /// camera path or the scene's camera). Used by the interactive viewer; safe to call
    /// while other threads trace.
    pub fn set_live_camera(&self, camera: Option<Camera>) {
        let mut live = self.live_camera.write().unwrap_or_else(|e| e.into_inner());
        if live.1 == camera {
            return;
        }
        let generation = live.0 + 1;
        *live = (generation, camera);
        self.camera_generation.store(generation, Ordering::Release);
    }

    /// The live camera override, if any.
    pub fn live_camera(&self) -> Option<Camera> {
        self.live_camera.read().unwrap_or_else(|e| e.into_inner()).1
    }

    /// Changes whenever the live camera changes: a state cached by a caller under
    /// `(quantize(t), camera_generation())` is current while both match.
    pub fn camera_generation(&self) -> u64 {
        self.camera_generation.load(Ordering::Acquire)
    }

    /// The view (camera path, else the scene's camera; the live camera overrides both)
    /// at time `t`, unquantized.
    pub fn camera_at(&self, t: f64) -> Camera {
        self.live_camera()
            .unwrap_or_else(|| self.scripted_camera(t as f32))
    }

    /// The camera path's view at `t`, else the scene's own camera's.
    fn scripted_camera(&self, t: f32) -> Camera {
        match &self.camera_path {
            Some(p) => p.at(t),
            None => self.scene.camera_at(t),
        }
    }

    /// The view a state at `t` is traced from: the live camera, else the scripted one,
    /// extrapolated `ahead` seconds ([`Tracer::state_at_ahead`]).
    fn state_camera(&self, t: f32, live: Option<Camera>, ahead: f64) -> Camera {
        match live {
            Some(c) => c,
            None if ahead > 0.0 => extrapolated(
                self.scripted_camera(t - ahead as f32),
                self.scripted_camera(t),
            ),
            None => self.scripted_camera(t),
        }
    }

    /// Replace the scene's camera with a camera path.
    pub fn with_camera_path(mut self, path: Option<CameraPath>) -> Self {
        self.camera_path = path;
        self.cache.lock().unwrap_or_else(|e| e.into_inner()).clear();
        self
    }

    /// The scene being traced.
    pub fn scene(&self) -> &Arc<Scene> {
        &self.scene
    }

    /// Triangles left out of the BVHs because they can never show: degenerate (zero
    /// area), exact copies of another, or beyond the build's coordinate limit.
    pub fn dropped_triangles(&self) -> usize {
        self.static_geo.dropped
            + self
                .instance_groups
                .iter()
                .map(|(_, g)| g.dropped)
                .sum::<usize>()
    }

    /// Image size `(width, height)`.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Tracer options.
    pub fn options(&self) -> TraceOptions {
        self.options
    }

    /// Quantize a time to the state grid.
    pub fn quantize(t: f64) -> i64 {
        (t / TIME_QUANTUM).round() as i64
    }

    /// The scene state at time `t` (quantized to [`TIME_QUANTUM`]), cached.
    pub fn state_at(&self, t: f64) -> Arc<SceneState> {
        self.state_at_ahead(t, 0.0)
    }

    /// The scene state at time `t` (quantized to [`TIME_QUANTUM`]), its camera
    /// extrapolated `ahead` seconds (quantized too) along the line through its poses at
    /// `t - ahead` and `t`: only poses already past at `t`, as a display predicts
    /// where its viewer will look. The live camera is never extrapolated (it has no
    /// path); `ahead <= 0` is [`Tracer::state_at`]. Cached.
    pub fn state_at_ahead(&self, t: f64, ahead: f64) -> Arc<SceneState> {
        let key = Self::quantize(t);
        let akey = Self::quantize(ahead.max(0.0));
        let (generation, live) = *self.live_camera.read().unwrap_or_else(|e| e.into_inner());
        {
            let cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((_, s)) = cache.iter().find(|(k, _)| *k == (key, generation, akey)) {
                return s.clone();
            }
        }
        let state =
            Arc::new(self.build_state(key as f64 * TIME_QUANTUM, live, akey as f64 * TIME_QUANTUM));
        let mut cache = self.cache.lock().unwrap_or_else(|e| e.into_inner());
        if cache.len() >= CACHE_STATES {
            cache.remove(0);
        }
        cache.push(((key, generation, akey), state.clone()));
        state
    }

    fn build_state(&self, time: f64, live: Option<Camera>, ahead: f64) -> SceneState {
        let scene = &self.scene;
        let t = time as f32;
        let camera = self
            .state_camera(t, live, ahead)
            .frame(self.width, self.height);
        let lights = scene.lights_at(t);
        let mut instances = Vec::with_capacity(self.instance_groups.len());
        for (i, (node, g)) in self.instance_groups.iter().enumerate() {
            let ns = scene.node_state(*node, t);
            if !ns.visible || g.is_empty() {
                continue;
            }
            let det = ns.matrix.determinant();
            if det.abs() < 1e-30 || !det.is_finite() {
                continue; // squashed to nothing: invisible
            }
            instances.push(InstanceState {
                group: i as u32,
                world: ns.matrix,
                inv: ns.matrix.inverse(),
                normal: Mat3::from_mat4(ns.matrix).inverse().transpose(),
                velocity: ns.velocity,
                aabb: transform_aabb(&ns.matrix, &g.aabb),
            });
        }
        let mut instance_of_group = vec![u32::MAX; self.instance_groups.len()];
        for (k, inst) in instances.iter().enumerate() {
            instance_of_group[inst.group as usize] = k as u32;
        }
        let top = build_top_level(&instances);
        let anim = self.anim_base.as_ref().map(|base| {
            let data = anim_positions(scene, time);
            let mut bvh = base.clone();
            let tris: Vec<RtTriangle> = bvh
                .primitive_indices
                .iter()
                .map(|&i| RtTriangle::from(&data[i as usize].0))
                .collect();
            let normals = bvh
                .primitive_indices
                .iter()
                .map(|&i| data[i as usize].1)
                .collect();
            let velocities = bvh
                .primitive_indices
                .iter()
                .map(|&i| data[i as usize].2)
                .collect();
            for ni in 0..bvh.nodes.len() {
                let node = bvh.nodes[ni];
                if node.is_leaf() {
                    let mut b = Aabb::empty();
                    for k in node.first_index..node.first_index + node.prim_count {
                        b = b.union(&tris[k as usize].aabb());
                    }
                    bvh.nodes[ni].set_aabb(b);
                }
            }
            bvh.refit_all();
            AnimState {
                bvh,
                tris,
                normals,
                velocities,
            }
        });
        SceneState {
            time,
            camera,
            lights,
            instances,
            instance_of_group,
            top,
            anim,
        }
    }

    fn closest(&self, state: &SceneState, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut r = *ray;
        if let Some((t, p)) = self.static_geo.closest(&r) {
            best = Some(Hit {
                t,
                at: HitWhere::Static(p),
            });
            r.tmax = t;
        }
        if let Some(top) = &state.top {
            let mut rh = RayHit::none();
            top.ray_traverse(r, &mut rh, |wr, id| {
                let inst = &state.instances[top.primitive_indices[id] as usize];
                let local = inst.local_ray(wr);
                match self.instance_groups[inst.group as usize].1.closest(&local) {
                    Some((t, p)) => {
                        best = Some(Hit {
                            t,
                            at: HitWhere::Instance(top.primitive_indices[id], p),
                        });
                        t
                    }
                    None => f32::INFINITY,
                }
            });
            if let Some(h) = best {
                r.tmax = h.t;
            }
        }
        if let Some(anim) = &state.anim {
            let mut rh = RayHit::none();
            if anim
                .bvh
                .ray_traverse(r, &mut rh, |wr, id| anim.tris[id].intersect(wr))
            {
                best = Some(Hit {
                    t: rh.t,
                    at: HitWhere::Anim(rh.primitive_id),
                });
            }
        }
        best
    }

    /// Transmission along a shadow ray: 0 when blocked by an opaque surface, the
    /// product of transmissions of transmissive occluders otherwise.
    fn shadow(&self, state: &SceneState, ray: &Ray) -> (f32, bool) {
        let mats = &self.scene.materials;
        let tr = |m: MaterialId| mats.get(m as usize).map_or(0.0, |m| m.transmission);
        let mut acc = 1.0f32;
        if self.static_geo.occlusion(ray, &tr, &mut acc) {
            return (0.0, false);
        }
        let mut dynamic = false;
        if let Some(top) = &state.top {
            let mut blocked = false;
            top.ray_traverse_miss(*ray, |wr, id| {
                let inst = &state.instances[top.primitive_indices[id] as usize];
                let local = inst.local_ray(wr);
                let before = acc;
                let hit = self.instance_groups[inst.group as usize]
                    .1
                    .occlusion(&local, &tr, &mut acc);
                if (hit || acc != before) && inst.velocity != Mat4::ZERO {
                    dynamic = true;
                }
                if hit {
                    blocked = true;
                    0.0
                } else {
                    f32::INFINITY
                }
            });
            if blocked {
                return (0.0, dynamic);
            }
        }
        if let Some(anim) = &state.anim {
            let scene = &self.scene;
            let blocked = !anim.bvh.ray_traverse_miss(*ray, |wr, id| {
                let t = anim.tris[id].intersect(wr);
                if t.is_finite() {
                    dynamic |= anim.velocities[id] != [Vec3::ZERO; 3];
                    let src = anim.bvh.primitive_indices[id] as usize;
                    let m = tr(scene.animated_triangles[src].material);
                    if m > 0.0 {
                        acc *= m;
                        return f32::INFINITY;
                    }
                }
                t
            });
            if blocked {
                return (0.0, dynamic);
            }
        }
        (acc, dynamic)
    }

    fn surface(&self, state: &SceneState, ray: &Ray, hit: &Hit) -> Surface {
        let p_world = Vec3::from(ray.origin + ray.direction * hit.t);
        let group_surface =
            |g: &GroupAccel, pr: PrimRef, lray: &Ray| -> (Vec3, Vec3, Vec3, Vec2, MaterialId) {
                let pl = Vec3::from(lray.origin + lray.direction * hit.t);
                match pr {
                    PrimRef::Tri(i) => {
                        let tri = &g.tris[i as usize];
                        let a = &g.attrs[i as usize];
                        let bc = tri.compute_barycentric(lray);
                        let (u, v) = (bc.x, bc.y);
                        let w = 1.0 - u - v;
                        let ng = Vec3::from(tri.compute_normal());
                        let n = (a.n[0] * w + a.n[1] * u + a.n[2] * v).normalize_or(ng);
                        let uv = a.uv[0] * w + a.uv[1] * u + a.uv[2] * v;
                        (pl, ng, n, uv, a.material)
                    }
                    PrimRef::Analytic(i) => {
                        let an = &g.analytic[i as usize];
                        let n = an.normal(pl);
                        (pl, n, n, Vec2::ZERO, an.material())
                    }
                }
            };
        match hit.at {
            HitWhere::Static(pr) => {
                let (_, ng, n, uv, material) = group_surface(&self.static_geo, pr, ray);
                Surface {
                    p: p_world,
                    ng,
                    n,
                    uv,
                    material,
                    velocity: Vec3::ZERO,
                    anchor: Anchor::Still,
                }
            }
            HitWhere::Instance(ii, pr) => {
                let inst = &state.instances[ii as usize];
                let lray = inst.local_ray(ray);
                let g = &self.instance_groups[inst.group as usize].1;
                let (pl, ng, n, uv, material) = group_surface(g, pr, &lray);
                Surface {
                    p: p_world,
                    ng: (inst.normal * ng).normalize_or(Vec3::Y),
                    n: (inst.normal * n).normalize_or(Vec3::Y),
                    uv,
                    material,
                    velocity: inst.velocity.transform_point3(pl),
                    anchor: Anchor::Instance {
                        group: inst.group,
                        local: pl,
                    },
                }
            }
            HitWhere::Anim(i) => {
                let anim = state.anim.as_ref().expect("anim hit implies anim state");
                let tri = &anim.tris[i as usize];
                let bc = tri.compute_barycentric(ray);
                let (u, v) = (bc.x, bc.y);
                let w = 1.0 - u - v;
                let ng = Vec3::from(tri.compute_normal());
                let nn = &anim.normals[i as usize];
                let vv = &anim.velocities[i as usize];
                let src = anim.bvh.primitive_indices[i as usize] as usize;
                Surface {
                    p: p_world,
                    ng,
                    n: (nn[0] * w + nn[1] * u + nn[2] * v).normalize_or(ng),
                    uv: Vec2::ZERO,
                    material: self.scene.animated_triangles[src].material,
                    velocity: vv[0] * w + vv[1] * u + vv[2] * v,
                    anchor: Anchor::Triangle { index: i, u, v },
                }
            }
        }
    }

    /// UV area per unit world area of the hit primitive (ray-cone texture filtering).
    /// Only triangles of rigid groups carry texture coordinates; everything else has a
    /// constant UV, density 0.
    fn uv_density(&self, state: &SceneState, hit: &Hit) -> f32 {
        let (g, i, m) = match hit.at {
            HitWhere::Static(PrimRef::Tri(i)) => (&self.static_geo, i, None),
            HitWhere::Instance(ii, PrimRef::Tri(i)) => {
                let inst = &state.instances[ii as usize];
                let g = &self.instance_groups[inst.group as usize].1;
                (g, i, Some(Mat3::from_mat4(inst.world)))
            }
            _ => return 0.0,
        };
        let tri = &g.tris[i as usize];
        let uv = &g.attrs[i as usize].uv;
        let uv_area2 = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs();
        let world_area2 = match m {
            None => tri.ng.length(),
            Some(m) => (m * Vec3::from(tri.e1))
                .cross(m * Vec3::from(tri.e2))
                .length(),
        };
        if world_area2 > 0.0 {
            uv_area2 / world_area2
        } else {
            0.0
        }
    }

    /// The footprint at `hit` of a cone that left the ray's origin as `cone`, when
    /// filtering by ray cones.
    #[inline]
    fn footprint(&self, state: &SceneState, hit: &Hit, cone: Option<RayCone>) -> Option<Footprint> {
        cone.map(|c| Footprint {
            cone: c.advance(hit.t),
            uv_density: self.uv_density(state, hit),
        })
    }

    /// Offset for secondary ray origins, relative to the scene's size.
    fn epsilon(&self, p: Vec3) -> f32 {
        1e-5 * self.scene_scale.max(p.abs().max_element())
    }

    /// Whether a primary ray through pixel coordinates `(x, y)` hits anything, and
    /// where (distance). Primary visibility only: the cheapest query, used by benchmarks.
    pub fn primary_hit(&self, state: &SceneState, x: f32, y: f32) -> Option<f32> {
        let ray = self.primary_ray(state, x, y);
        self.closest(state, &ray).map(|h| h.t)
    }

    /// What a primary ray through `(x, y)` hits, and at which distance (`INFINITY` on a
    /// miss): what the GPU tracer's equivalence is judged by.
    pub fn primary_hit_id(&self, state: &SceneState, x: f32, y: f32) -> (HitId, f32) {
        let ray = self.primary_ray(state, x, y);
        let hit = self.closest(state, &ray);
        (
            HitId::of(state, hit.as_ref()),
            hit.map_or(f32::INFINITY, |h| h.t),
        )
    }

    fn primary_ray(&self, state: &SceneState, x: f32, y: f32) -> Ray {
        let cam = &state.camera;
        Ray::new(
            Vec3A::from(cam.eye),
            Vec3A::from(cam.direction(x, y)),
            cam.hither.max(0.0),
            f32::INFINITY,
        )
    }

    /// Trace one fully shaded sample through continuous pixel coordinates `(x, y)` in
    /// the given state.
    pub fn sample(&self, state: &SceneState, x: f32, y: f32) -> Sample {
        let ray = self.primary_ray(state, x, y);
        match self.closest(state, &ray) {
            None => {
                let c = self.scene.background;
                Sample {
                    color: c,
                    luminance: luminance(c),
                    hit_point: Vec3::from(ray.origin + ray.direction * 1e6),
                    depth: f32::INFINITY,
                    velocity: Vec3::ZERO,
                    hit: false,
                    dynamic: false,
                    anchor: Anchor::Still,
                }
            }
            Some(h) => {
                let s = self.surface(state, &ray, &h);
                let cone = match self.options.texture_filter {
                    TextureFilter::None => None,
                    TextureFilter::RayCones => Some(RayCone::primary(&state.camera)),
                };
                let fp = self.footprint(state, &h, cone);
                let (c, dynamic) = self.shade(state, &ray, &s, fp, 0);
                Sample {
                    color: c,
                    luminance: luminance(c),
                    hit_point: s.p,
                    depth: h.t,
                    velocity: s.velocity,
                    hit: true,
                    dynamic,
                    anchor: s.anchor,
                }
            }
        }
    }

    /// Trace one sample at pixel coordinates `(x, y)` and time `t` (the tracer's
    /// `trace(x, y, t)`); the scene state comes from the cache.
    pub fn trace(&self, x: f32, y: f32, t: f64) -> Sample {
        let state = self.state_at(t);
        self.sample(&state, x, y)
    }

    /// Whether the segment from `from` to `to` is blocked (the sampler's occlusion test).
    pub fn occluded(&self, state: &SceneState, from: Vec3, to: Vec3) -> bool {
        let d = to - from;
        let len = d.length();
        if len == 0.0 {
            return false;
        }
        let eps = self.epsilon(from);
        let ray = Ray::new(from.into(), (d / len).into(), eps, (len - eps).max(0.0));
        self.closest(state, &ray).is_some()
    }
}

/// World-space positions, normals and velocities of the animated triangles at `t`.
fn anim_positions(scene: &Scene, t: f64) -> Vec<(ObTriangle, [Vec3; 3], [Vec3; 3])> {
    let tf = t as f32;
    scene
        .animated_triangles
        .iter()
        .map(|at| {
            let (p, n, v) = at.eval(tf);
            let (p, n, v) = match at.node {
                Some(node) => {
                    let ns = scene.node_state(node, tf);
                    let nm = Mat3::from_mat4(ns.matrix).inverse().transpose();
                    (
                        p.map(|x| ns.matrix.transform_point3(x)),
                        n.map(|x| (nm * x).normalize_or(Vec3::Y)),
                        std::array::from_fn(|i| {
                            ns.matrix.transform_vector3(v[i]) + ns.velocity.transform_point3(p[i])
                        }),
                    )
                }
                None => (p, n, v),
            };
            (
                ObTriangle {
                    v0: p[0].into(),
                    v1: p[1].into(),
                    v2: p[2].into(),
                },
                n,
                v,
            )
        })
        .collect()
}
