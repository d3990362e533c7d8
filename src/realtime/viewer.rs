//! The interactive viewer: a winit window whose contents softbuffer fills with the
//! newest image of the pipeline at every display refresh.
//!
//! Keys: W/S or ↑/↓ move forward/back, A/D strafe, ←/→ turn, Q/E down/up, Shift ×4
//! speed, left mouse drag looks around; the digit keys switch methods in
//! [`RtMethod::ALL`] order (1 adaptive, 2 traditional frameless, 3 framed, 4 late
//! warp, 5 taa, 6 taa-warp); V cycles the visualisation (the image, then the overlays
//! the method offers: adaptive's tiling, gradients and density); P writes a screenshot; Esc quits. The title bar shows samples/s, display FPS, the mean and 95th-percentile age
//! of the information on screen, the visualisation with its colour key, and where the
//! images are reconstructed (`recon: cpu`, or `recon: gpu (adapter)`). Neither X11 nor Wayland libraries are linked: winit and
//! softbuffer load them at run time.

use std::{
    collections::HashSet,
    num::NonZeroU32,
    path::PathBuf,
    rc::Rc,
    sync::Arc,
    time::{Duration, Instant},
};

use winit::{
    application::ApplicationHandler,
    dpi::PhysicalSize,
    event::{ElementState, MouseButton, StartCause, WindowEvent},
    event_loop::{ActiveEventLoop, ControlFlow, EventLoop},
    keyboard::{KeyCode, PhysicalKey},
    window::{Window, WindowId},
};

use super::{
    camera::{CameraRecorder, FlyCamera},
    config::{RealtimeError, RtConfig},
    pacing::Pacer,
    pipeline::Pipeline,
    registry::{RtMethod, RtSettings, Visualisation},
};
use crate::{image::Image, trace::Tracer};

/// Settings of the viewer.
#[derive(Clone, Debug, Default)]
pub struct ViewerOptions {
    /// Close after this many seconds (tests, screenshots).
    pub seconds: Option<f64>,
    /// Record the camera path to this CSV file (written on exit).
    pub record: Option<PathBuf>,
    /// Write the last displayed image here on exit.
    pub screenshot: Option<PathBuf>,
    /// Visualisation shown at start.
    pub visualisation: Visualisation,
    /// The settings of methods the digit keys switch to; one not here starts with its
    /// defaults.
    pub others: Vec<RtSettings>,
}

/// winit's message without the source file and line it names (`os error at
/// <file>:<line>: <what>` becomes `<what>`): a user is told what is wrong, not where in
/// a dependency.
fn without_source_location(msg: &str) -> String {
    let Some(rest) = msg.strip_prefix("os error at ") else {
        return msg.trim_end_matches('.').to_string();
    };
    // `<file>:<line>: <what>`: the first `: ` after a run of digits.
    let what = rest
        .match_indices(": ")
        .find(|(i, _)| {
            let before = &rest[..*i];
            let digits = before.len() - before.trim_end_matches(|c: char| c.is_ascii_digit()).len();
            digits > 0 && before[..before.len() - digits].ends_with(':')
        })
        .map_or(rest, |(i, _)| &rest[i + 2..]);
    what.trim_end_matches('.').to_string()
}

/// Open the window and run until it is closed (or `opts.seconds` pass).
pub fn run_viewer(
    tracer: Arc<Tracer>,
    config: RtConfig,
    settings: RtSettings,
    opts: ViewerOptions,
) -> Result<(), RealtimeError> {
    let event_loop = EventLoop::new().map_err(|e| {
        RealtimeError::Window(format!(
            "cannot open a window ({}); is DISPLAY or WAYLAND_DISPLAY set? A headless run (--headless) needs neither",
            without_source_location(&e.to_string())
        ))
    })?;
    let pipeline = Pipeline::start(tracer, config.clone(), settings)?;
    let pacer = Pacer::new(pipeline.clock(), config.refresh_hz);
    let mut app = App {
        opened: Instant::now(),
        pipeline: Some(pipeline),
        pacer,
        config,
        opts,
        window: None,
        surface: None,
        fly: None,
        keys: HashSet::new(),
        dragging: false,
        cursor: None,
        last_move: Instant::now(),
        recorder: CameraRecorder::new(),
        shown: Image::new(1, 1),
        shown_seq: 0,
        title_at: Instant::now(),
        title_samples: 0,
        title_images: 0,
        screenshots: 0,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| RealtimeError::Window(e.to_string()))?;
    app.finish()
}

/// Digit key n switches to the n-th method of [`RtMethod::ALL`].
fn method_key(code: KeyCode) -> Option<RtMethod> {
    use KeyCode::*;
    const DIGITS: [KeyCode; 9] = [
        Digit1, Digit2, Digit3, Digit4, Digit5, Digit6, Digit7, Digit8, Digit9,
    ];
    let i = DIGITS.iter().position(|&d| d == code)?;
    RtMethod::ALL.get(i).copied()
}

struct App {
    opened: Instant,
    pipeline: Option<Pipeline>,
    pacer: Pacer,
    config: RtConfig,
    opts: ViewerOptions,
    window: Option<Rc<Window>>,
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    fly: Option<FlyCamera>,
    keys: HashSet<KeyCode>,
    dragging: bool,
    cursor: Option<(f64, f64)>,
    last_move: Instant,
    recorder: CameraRecorder,
    shown: Image,
    shown_seq: u64,
    title_at: Instant,
    title_samples: u64,
    title_images: u64,
    screenshots: u32,
    error: Option<RealtimeError>,
}

impl App {
    fn pipeline(&self) -> &Pipeline {
        self.pipeline
            .as_ref()
            .expect("pipeline runs while the window is open")
    }

    fn fail(&mut self, el: &ActiveEventLoop, e: RealtimeError) {
        self.error.get_or_insert(e);
        el.exit();
    }

    /// Stop the pipeline, write the recording and the screenshot.
    fn finish(mut self) -> Result<(), RealtimeError> {
        if let Some(p) = self.pipeline.take() {
            p.stop()?;
        }
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        if let Some(path) = &self.opts.record {
            let csv = self.recorder.to_csv().unwrap_or_default();
            std::fs::write(path, csv).map_err(|source| RealtimeError::Io {
                path: path.clone(),
                source,
            })?;
            eprintln!(
                "recorded {} camera keys to {}",
                self.recorder.len(),
                path.display()
            );
        }
        if let Some(path) = &self.opts.screenshot {
            self.shown
                .save_png(path)
                .map_err(|source| RealtimeError::Io {
                    path: path.clone(),
                    source,
                })?;
        }
        Ok(())
    }

    fn switch_method(&mut self, m: RtMethod) -> Result<(), RealtimeError> {
        if m == self.method() {
            return Ok(());
        }
        if self.config.rays.is_some() && !m.traces_on_gpu() {
            // A run traced on the GPU stays with the methods that trace there, rather
            // than stop the viewer or trace on the CPU.
            eprintln!("{}", super::registry::cannot_trace_on_gpu(m));
            return Ok(());
        }
        let settings = self.opts.others.iter().find(|s| s.method() == m);
        let settings = settings.cloned().unwrap_or_else(|| m.settings());
        let old = self.pipeline.take().expect("pipeline runs");
        let tracer = old.tracer().clone();
        let now = old.clock().now();
        old.stop()?;
        // Scene time goes on where it was.
        self.config.start = now;
        let p = Pipeline::start(tracer, self.config.clone(), settings)?;
        self.pacer = Pacer::new(p.clock(), self.config.refresh_hz);
        self.title_samples = 0;
        self.title_images = 0;
        self.pipeline = Some(p);
        Ok(())
    }

    /// The method running now.
    fn method(&self) -> RtMethod {
        self.pipeline().settings().method()
    }

    fn fly(&mut self) -> &mut FlyCamera {
        if self.fly.is_none() {
            let p = self.pipeline();
            let c = p.tracer().camera_at(p.clock().now());
            self.fly = Some(FlyCamera::from_camera(&c));
        }
        self.fly.as_mut().expect("just set")
    }

    /// Apply held keys for the time since the last update.
    fn move_camera(&mut self) {
        let dt = self.last_move.elapsed().as_secs_f32().min(0.1);
        self.last_move = Instant::now();
        let k = |c: KeyCode| self.keys.contains(&c) as i32 as f32;
        let fwd = k(KeyCode::KeyW) + k(KeyCode::ArrowUp) - k(KeyCode::KeyS) - k(KeyCode::ArrowDown);
        let right = k(KeyCode::KeyD) - k(KeyCode::KeyA);
        let up = k(KeyCode::KeyE) - k(KeyCode::KeyQ);
        let turn = k(KeyCode::ArrowLeft) - k(KeyCode::ArrowRight);
        if fwd == 0.0 && right == 0.0 && up == 0.0 && turn == 0.0 {
            return;
        }
        let fast = if self.keys.contains(&KeyCode::ShiftLeft)
            || self.keys.contains(&KeyCode::ShiftRight)
        {
            4.0
        } else {
            1.0
        };
        let f = self.fly();
        // A quarter of the distance to the point looked at per second: scenes come in
        // any unit.
        let speed = 0.25 * f.focus.max(0.1) * fast * dt;
        f.translate(right * speed, up * speed, fwd * speed);
        f.rotate(turn * 1.2 * dt, 0.0);
        let cam = f.camera();
        self.pipeline().tracer().set_live_camera(Some(cam));
    }

    fn redraw(&mut self) -> Result<(), RealtimeError> {
        self.move_camera();
        let p = self.pipeline.as_ref().expect("pipeline runs");
        let frame = p.latest();
        let seq = frame.as_ref().map_or(0, |f| f.seq);
        let now = p.clock().now();
        self.recorder.record(now, p.tracer().camera_at(now));
        if let Some(f) = &frame {
            if f.seq != self.shown_seq {
                let overlay = self.opts.visualisation.overlay().zip(f.overlays.as_ref());
                self.shown = overlay
                    .and_then(|(o, draw)| draw.draw(o.name, &f.image))
                    .unwrap_or_else(|| f.image.clone());
                self.shown_seq = f.seq;
            }
        }
        let (Some(window), Some(surface)) = (&self.window, &mut self.surface) else {
            return Ok(());
        };
        let size = window.inner_size();
        let (Some(ww), Some(wh)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height))
        else {
            return Ok(());
        };
        let win = |e: softbuffer::SoftBufferError| RealtimeError::Window(e.to_string());
        surface.resize(ww, wh).map_err(win)?;
        let mut buf = surface.buffer_mut().map_err(win)?;
        let img = &self.shown;
        let rgb = img.to_rgb8();
        let (iw, ih) = (img.width as usize, img.height as usize);
        let (ww, wh) = (size.width as usize, size.height as usize);
        // Nearest-neighbour scaling to the window.
        let cols: Vec<usize> = (0..ww).map(|x| (x * iw / ww).min(iw - 1)).collect();
        for y in 0..wh {
            let sy = (y * ih / wh).min(ih - 1);
            let row = &mut buf[y * ww..(y + 1) * ww];
            for (x, px) in row.iter_mut().enumerate() {
                let i = (sy * iw + cols[x]) * 3;
                *px = (rgb[i] as u32) << 16 | (rgb[i + 1] as u32) << 8 | rgb[i + 2] as u32;
            }
        }
        window.pre_present_notify();
        buf.present().map_err(win)?;
        self.pacer.present(seq);
        if self.title_at.elapsed() >= Duration::from_millis(500) {
            let st = p.stats();
            let dt = self.title_at.elapsed().as_secs_f64();
            let sps = (st.samples.saturating_sub(self.title_samples)) as f64 / dt;
            let shown = self.pacer.images_shown();
            let fps = shown.saturating_sub(self.title_images) as f64 / dt;
            self.title_samples = st.samples;
            self.title_images = shown;
            self.title_at = Instant::now();
            let age = frame.as_ref().map_or(f64::NAN, |f| f.mean_age);
            let p95 = frame
                .as_ref()
                .map_or(f64::NAN, |f| super::shared::quantile_of(&f.ages, 0.95));
            let threads = self.config.sampling_threads;
            window.set_title(&format!(
                "frameless · {} · {:.2} M samples/s · {:.0} fps · age {:.0} ms (p95 {:.0}) · {} · recon: {} · {} thread{}{}",
                self.method().name(),
                sps / 1e6,
                fps,
                age * 1e3,
                p95 * 1e3,
                self.opts.visualisation.key(),
                st.recon,
                threads,
                if threads == 1 { "" } else { "s" },
                if self.opts.record.is_some() {
                    " · REC"
                } else {
                    ""
                },
            ));
        }
        Ok(())
    }

    fn screenshot(&mut self) -> Result<(), RealtimeError> {
        self.screenshots += 1;
        let path = PathBuf::from(format!("frameless-screenshot-{}.png", self.screenshots));
        self.shown
            .save_png(&path)
            .map_err(|source| RealtimeError::Io {
                path: path.clone(),
                source,
            })?;
        eprintln!("wrote {}", path.display());
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let (w, h) = self.pipeline().tracer().size();
        let scale = (1024 / w).min(768 / h).clamp(1, 4);
        let attrs = Window::default_attributes()
            .with_title("frameless")
            .with_inner_size(PhysicalSize::new(w * scale, h * scale));
        let window = match el.create_window(attrs) {
            Ok(w) => Rc::new(w),
            Err(e) => return self.fail(el, RealtimeError::Window(e.to_string())),
        };
        let surface = softbuffer::Context::new(window.clone())
            .and_then(|ctx| softbuffer::Surface::new(&ctx, window.clone()));
        match surface {
            Ok(s) => self.surface = Some(s),
            Err(e) => return self.fail(el, RealtimeError::Window(e.to_string())),
        }
        self.window = Some(window);
    }

    fn new_events(&mut self, el: &ActiveEventLoop, _cause: StartCause) {
        if self
            .opts
            .seconds
            .is_some_and(|s| self.opened.elapsed().as_secs_f64() >= s)
        {
            el.exit();
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                el.exit();
                Ok(())
            }
            WindowEvent::RedrawRequested => self.redraw(),
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return;
                };
                if event.state == ElementState::Released {
                    self.keys.remove(&code);
                    return;
                }
                self.keys.insert(code);
                if event.repeat {
                    return;
                }
                match code {
                    KeyCode::Escape => {
                        el.exit();
                        Ok(())
                    }
                    KeyCode::KeyV => {
                        self.opts.visualisation = self.opts.visualisation.next(self.method());
                        self.shown_seq = 0;
                        Ok(())
                    }
                    KeyCode::KeyP => self.screenshot(),
                    _ => match method_key(code) {
                        Some(m) => self.switch_method(m),
                        None => Ok(()),
                    },
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.dragging = state == ElementState::Pressed;
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                let (x, y) = (position.x, position.y);
                if let (true, Some((px, py))) = (self.dragging, self.cursor) {
                    let f = self.fly();
                    f.rotate(-(x - px) as f32 * 0.004, -(y - py) as f32 * 0.004);
                    let cam = f.camera();
                    self.pipeline().tracer().set_live_camera(Some(cam));
                }
                self.cursor = Some((x, y));
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(el, e);
        }
    }

    fn about_to_wait(&mut self, el: &ActiveEventLoop) {
        if let Some(w) = &self.window {
            if self.pacer.due() {
                w.request_redraw();
            }
        }
        el.set_control_flow(ControlFlow::WaitUntil(self.pacer.next_due()));
    }
}

#[cfg(test)]
mod tests {
    use super::without_source_location;

    #[test]
    fn window_errors_name_the_problem_not_the_source_file() {
        let m = "os error at /root/.cargo/registry/src/x/winit-0.30.13/src/platform_impl/linux/mod.rs:765: neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set.";
        assert_eq!(
            without_source_location(m),
            "neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set"
        );
        assert_eq!(
            without_source_location("the event loop was created twice"),
            "the event loop was created twice"
        );
    }
}
