//! The GPU device: which adapter a run gets for `--recon gpu|auto` (and `--trace`).
//!
//! `gpu` takes the best adapter there is, a software one (Mesa's lavapipe) included;
//! `auto` never takes a software adapter unless `WGPU_ADAPTER_NAME` names it, so that
//! a machine without a GPU works on its own cores instead of emulating one on
//! them. `WGPU_BACKEND` and `WGPU_ADAPTER_NAME` narrow the choice as wgpu documents.

use std::sync::Arc;

use super::DeviceUsed;
use crate::settings::ReconDevice;

/// Why no GPU could be had, or GPU work failed.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter at all (or none matching `WGPU_ADAPTER_NAME`).
    #[error("no GPU adapter found{0} (install a Vulkan driver, e.g. Mesa's lavapipe: apt-get install mesa-vulkan-drivers libvulkan1; or run on the CPU)")]
    NoAdapter(String),
    /// The adapter refused a device.
    #[error("the GPU adapter {adapter} gave no device: {why}")]
    Device {
        /// The adapter in words.
        adapter: String,
        /// What wgpu said.
        why: String,
    },
    /// The adapter's limits are below what a GPU stage needs.
    #[error("the GPU adapter {adapter} is too small for this work: {why}")]
    Limits {
        /// The adapter in words.
        adapter: String,
        /// Which limit, and what was needed.
        why: String,
    },
    /// A GPU operation failed.
    #[error("GPU work failed: {0}")]
    Failed(String),
}

/// A device and its queue, shared by every GPU stage of a run (reconstructors, tracers).
pub struct GpuContext {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    pub(crate) limits: wgpu::Limits,
    info: wgpu::AdapterInfo,
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.describe())
            .finish()
    }
}

/// Rank of an adapter kind: hardware first, software last.
fn rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

impl GpuContext {
    /// The device `choice` asks for: `Ok(None)` for `cpu`, and for `auto` where there is
    /// no hardware adapter; an error for `gpu` where there is no adapter at all.
    pub fn acquire(choice: ReconDevice) -> Result<Option<Arc<GpuContext>>, GpuError> {
        if choice == ReconDevice::Cpu {
            return Ok(None);
        }
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let named = std::env::var("WGPU_ADAPTER_NAME")
            .ok()
            .map(|n| n.to_lowercase());
        let mut fit: Vec<wgpu::Adapter> = adapters
            .into_iter()
            .filter(|a| {
                let info = a.get_info();
                match &named {
                    Some(n) => info.name.to_lowercase().contains(n),
                    None => choice == ReconDevice::Gpu || info.device_type != wgpu::DeviceType::Cpu,
                }
            })
            .collect();
        fit.sort_by_key(|a| rank(a.get_info().device_type));
        let Some(adapter) = fit.into_iter().next() else {
            return match (choice, &named) {
                (ReconDevice::Auto, None) => Ok(None),
                (_, Some(n)) => Err(GpuError::NoAdapter(format!(
                    " whose name contains '{n}' (WGPU_ADAPTER_NAME)"
                ))),
                _ => Err(GpuError::NoAdapter(String::new())),
            };
        };
        Self::open(adapter).map(|c| Some(Arc::new(c)))
    }

    fn open(adapter: wgpu::Adapter) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        let limits = adapter.limits();
        let name = describe(&info);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("frameless"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device {
            adapter: name.clone(),
            why: e.to_string(),
        })?;
        Ok(Self {
            device,
            queue,
            limits,
            info,
        })
    }

    /// Whether the adapter is a software one (such as Mesa's lavapipe): its speed is
    /// the CPU's, not a GPU's.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Fail with [`GpuError::Limits`] unless the adapter binds `needed` storage buffers
    /// in one shader stage (what a stage's shaders bind at once).
    pub fn require_storage_buffers(&self, needed: u32) -> Result<(), GpuError> {
        let have = self.limits.max_storage_buffers_per_shader_stage;
        if have < needed {
            return Err(GpuError::Limits {
                adapter: self.describe(),
                why: format!("{have} storage buffers per shader stage, {needed} needed"),
            });
        }
        Ok(())
    }

    /// The adapter in words: name, driver, backend and kind.
    pub fn describe(&self) -> String {
        describe(&self.info)
    }

    /// What results record of it.
    pub fn used(&self) -> DeviceUsed {
        DeviceUsed {
            device: "gpu".into(),
            adapter: Some(self.describe()),
        }
    }

    /// `take` of the first `bytes` of the read-back buffer `buf`, read in place from
    /// its mapping once submission `index` is done (`None`: all work submitted so
    /// far); then the buffer is unmapped.
    pub fn read_mapped<R>(
        &self,
        buf: &wgpu::Buffer,
        bytes: u64,
        index: Option<wgpu::SubmissionIndex>,
        take: impl FnOnce(&[u8]) -> R,
    ) -> Result<R, GpuError> {
        self.read_mapped_all(&[(buf, bytes)], index, |views| take(views[0]))
    }

    /// [`GpuContext::read_mapped`] of several read-back buffers at once, after one
    /// wait: `take` sees every mapping or is not called, so that a failure leaves
    /// whatever it would have written untouched.
    pub fn read_mapped_all<R>(
        &self,
        bufs: &[(&wgpu::Buffer, u64)],
        index: Option<wgpu::SubmissionIndex>,
        take: impl FnOnce(&[&[u8]]) -> R,
    ) -> Result<R, GpuError> {
        let failed = |e: &dyn std::fmt::Display| GpuError::Failed(e.to_string());
        let (tx, rx) = std::sync::mpsc::channel();
        for &(buf, bytes) in bufs {
            let tx = tx.clone();
            buf.slice(0..bytes)
                .map_async(wgpu::MapMode::Read, move |r| {
                    let _ = tx.send(r);
                });
        }
        drop(tx);
        // A failure gives the device up (callers drop it), so nothing is unmapped then.
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: index,
                timeout: None,
            })
            .map_err(|e| failed(&e))
            .and_then(|_| {
                (0..bufs.len()).try_for_each(|_| match rx.recv() {
                    Ok(r) => r.map_err(|e| failed(&e)),
                    Err(e) => Err(failed(&e)),
                })
            })?;
        let views = bufs
            .iter()
            .map(|&(buf, bytes)| {
                buf.slice(0..bytes)
                    .get_mapped_range()
                    .map_err(|e| failed(&e))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let slices: Vec<&[u8]> = views.iter().map(|v| &v[..]).collect();
        let got = take(&slices);
        // Every view must be gone before its buffer is unmapped.
        drop(views);
        bufs.iter().for_each(|(b, _)| b.unmap());
        Ok(got)
    }
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => "discrete GPU",
        wgpu::DeviceType::IntegratedGpu => "integrated GPU",
        wgpu::DeviceType::VirtualGpu => "virtual GPU",
        wgpu::DeviceType::Cpu => "software, on the CPU",
        wgpu::DeviceType::Other => "other",
    };
    let driver = [info.driver.as_str(), info.driver_info.as_str()]
        .iter()
        .filter(|s| !s.is_empty())
        .copied()
        .collect::<Vec<_>>()
        .join(" ");
    format!("{}, {driver}, {:?}, {kind}", info.name, info.backend)
}
