#!/usr/bin/env bash
# The figures the open issues ask of a machine with a GPU and 16 cores, in one run of
# about 9 minutes, for a session that is lent one (the device tool). The machine has no
# network and no Vulkan loader: build here, fetch the loaders once as the device tool's
# README says (into .gl/, ignored), and carry them with the stripped binaries. Build them
# for any AVX2 x86-64, not for this machine's CPU (.cargo/config.toml's target-cpu=native):
# the device's Xeons differ between calls, and in session 23 a native build stopped with
# "Illegal instruction" in the GPU tracer's steps on an H200 host after running on an
# H100 host. Its own target folder keeps the native build's cache:
#   RUSTFLAGS="-C target-cpu=x86-64-v3" cargo build --release --target-dir target/device \
#     --bin frameless --example live_recon
#   strip -o target/frameless-stripped target/device/release/frameless
#   strip -o target/live_recon-stripped target/device/release/examples/live_recon
# then, on the device, with carry [".gl", "target/frameless-stripped",
# "target/live_recon-stripped"] (the tracked PNGs under docs/results may have to be
# removed from the working tree for the call, and restored after, to fit its 64 MiB):
#   for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
#   BUDGET_S=520 bash docs/results/device/run.sh 2>&1 | tee $OUT/run.log
# (ONLY=REGEX runs only the steps whose names match, for a short rerun.)
# SMOKE=1 runs every step at a twentieth of each side (the reconstructor alone at 10K
# samples a second), to check before a device session, on lavapipe, that each step
# still runs with this version (each step's exit status is in run.log); its figures
# mean nothing:
#   SMOKE=1 BUDGET_S=900 FRAMELESS=target/device/release/frameless \
#     LIVE_RECON=target/device/release/examples/live_recon bash docs/results/device/run.sh
# Only eight files come back from the device, so everything is written under a work
# folder and packed into $OUT/results.tar.gz (images left out). Steps, in order of
# value, each cut to what is left of the time budget:
# - live_1280x720_16/, live_1920x1080_all/: `frameless live` of adaptive against
#   traditional frameless on every core (the image-cost issue's scaling; their ideals
#   fill the cache the 2-core runs read);
# - live_<size>_2cores_gpurecon/: the image-cost issue's 2-core cases at 1280x720 and
#   1920x1080 (where adaptive's CPU build misses 30 Hz) with rays on the CPU and images
#   on the GPU, against traditional frameless and late warp, and
#   live_<size>_2cores_gpurecon_nolimit/: adaptive there without the live limit;
# - live_recon_gpu.log: the reconstructor alone on the GPU at live rates (the live-recon
#   bench's cases; `per pass` splits the CPU's parts from gpu_wait), its CPU parts on 1
#   thread and on every core, with the sums carried (still) and the ring of 6 samples a
#   pixel re-splatted under a still camera (resplat still: no carry), at 1920x1080,
#   1280x720 and 640x480;
# - live_<size>_2cores_gpu/: adaptive, traditional frameless and late warp at 640x480,
#   1280x720 and 1920x1080, 30 Hz, on 2 cores with rays and images on the GPU;
# - live_<size>_<cores>/: the rest of the scaling, 640x480 on 16, 8 and 4 cores and
#   1280x720 on 8 and 4 (new images/s, samples/s, and `pass_ms`, the build's steps);
# - live_<size>_<cores>_recon<cores>/: adaptive with the image build on every core;
# - live_<size>_gpurecon/: adaptive on every core with the images on the GPU
#   (`pass_ms` splits the GPU's part into gpu_upload, gpu_wait and gpu_read;
#   `gpu_carried_sums` says how many refreshes replayed the CPU's carry on the GPU);
# - live_recon.log: the reconstructor alone at 1280x720 on 1 and 8 threads;
# - bench_trace_gpu.log and live_1920x1080_gputrace/: the GPU tracer's rays/s and its
#   16-spp ideal against the CPU's at 1920x1080, and 60 Hz live traced and built on the
#   GPU (its issue is resolved; these follow later changes);
# - view_2cores_recon<N>.log: 1280x720 on 2 cores, the image build on 1 or 2 threads;
# - bench_gpu.log: `frameless bench --recon gpu`.
set -uo pipefail
bin="${FRAMELESS:-target/frameless-stripped}"
ex="${LIVE_RECON:-target/live_recon-stripped}"
out="${OUT:-/tmp/device-out}"
work="$(mktemp -d)"
cache="$work/ideal-cache"
budget="${BUDGET_S:-330}"
mkdir -p "$out" "$cache"
[ -x "$bin" ] || { echo "error: $bin not found: build and carry the release binary" >&2; exit 1; }
bin="$(realpath "$bin")"
[ -x "$ex" ] && ex="$(realpath "$ex")"
start=$SECONDS
smoke="${SMOKE:-}"
# sz WxH: the size a step runs at (a twentieth of each side with SMOKE).
sz() { if [ -z "$smoke" ]; then echo "$1"; else echo "$((${1%x*} / 20))x$((${1#*x} / 20))"; fi; }
# case 'W H RATE HZ': a live_recon case at the size and sample rate a step runs at.
case_of() {
  set -- $1
  if [ -z "$smoke" ]; then echo "$1 $2 $3 $4"; else echo "$(($1 / 20)) $(($2 / 20)) 1e4 $4"; fi
}
if [ -z "${VK_DRIVER_FILES:-}" ] && [ -e /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ]; then
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
fi

# step NAME MAX_SECONDS COMMAND...: run with a timeout of at most what is left.
step() {
  local name="$1" max="$2"; shift 2
  if [ -n "${ONLY:-}" ] && ! [[ "$name" =~ $ONLY ]]; then return; fi
  local left=$((budget - (SECONDS - start)))
  local t=$((max < left ? max : left))
  if [ "$t" -lt 15 ]; then echo "skipped $name: time budget spent"; return; fi
  local t0=$SECONDS
  timeout "$t" "$@" > "$work/$name.log" 2>&1
  echo "$name: exit $? in $((SECONDS - t0)) s (limit $t s)"
}

{
  echo "cores: $(nproc)"
  lscpu | grep -E 'Model name|MHz' | head -3
  free -g | head -2
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv 2>&1 || echo "nvidia-smi: none"
  ldconfig -p | grep -i libvulkan || echo "no Vulkan loader"
} > "$work/machine.txt"

live() { # live NAME CORES ARGS... (a `--size` among ARGS goes through sz)
  local name="$1" n="$2" a prev="" args=(); shift 2
  for a in "$@"; do
    if [ "$prev" = --size ]; then args+=("$(sz "$a")"); else args+=("$a"); fi
    prev="$a"
  done
  set -- "${args[@]}"
  step "$name" 110 taskset -c "0-$((n - 1))" "$bin" --threads "$n" live --scene toycar \
    --start 1 --duration 2 --warmup 1 --repeat 1 --ideal-spp 4 \
    --cache-dir "$cache" -o "$work/$name" "$@"
}

all=$(nproc)
has_trace() { "$bin" live --help 2>/dev/null | grep -q -- '--trace'; }
# The image-cost issue first. All cores at 1280x720 and 1920x1080 first: they are the
# issue's scaling figures, and their ideals fill the cache that the 2-core runs below
# read (2 cores would take minutes to trace 4-spp ideals at these sizes).
live live_1280x720_16 "$all" --size 1280x720 --refresh-hz 30 \
  --method adaptive,traditional-frameless
live live_1920x1080_all "$all" --size 1920x1080 --refresh-hz 30 \
  --method adaptive,traditional-frameless
# The issue's 2-core bars with only the images on the GPU: rays traced on the CPU, as
# in the committed 2-core tables, at the sizes where adaptive's CPU build misses 30 Hz.
for size in 1280x720 1920x1080; do
  live "live_${size}_2cores_gpurecon" 2 --size "$size" --refresh-hz 30 --recon gpu \
    --method adaptive,traditional-frameless,late-warp
done
# The same without the live limit: it cuts the samples an image places to fit its build
# in 80% of a period, as if the build cost followed them, which a GPU build's need not
# (session 26's GPU builds placed about the floor, a sixteenth of the pixels, and
# lavapipe's near none); does placing every sample that arrives do better there?
for size in 1280x720 1920x1080; do
  live "live_${size}_2cores_gpurecon_nolimit" 2 --size "$size" --refresh-hz 30 \
    --recon gpu --method adaptive --image-budget 0
done
# The reconstructor alone on the GPU at live rates (`per pass` splits the CPU's parts
# from gpu_wait, and the process's CPU time per image tells CPU work from waiting), on
# 1 thread and every core: the sums carried (still), and the ring re-splatted under a
# still camera (no carry). 1280x720 at 1 M samples/s first: about what 2 cores trace
# live (33K new samples an image, where a GPU image's per-pixel costs lead).
if [ -x "$ex" ]; then
  cases="'$(case_of '1280 720 1e6 30')' '$(case_of '1920 1080 4e6 30')' '$(case_of '1280 720 4e6 30')' '$(case_of '640 480 3e6 30')'"
  step live_recon_gpu 100 bash -c "for c in $cases; do
    for t in 1 $all; do for m in '2 still' '6 resplat still'; do
      echo \"\$c ring \$m threads=\$t gpu:\"; RAYON_NUM_THREADS=\$t '$ex' \$c \$m gpu; done; done; done"
fi
# 2 cores with rays and images on the GPU: do adaptive's new images keep up with 30 Hz,
# and does it beat the others there? (These runs trace their ideals on the GPU.)
if has_trace; then
  for size in 640x480 1280x720 1920x1080; do
    live "live_${size}_2cores_gpu" 2 --size "$size" --refresh-hz 30 --trace gpu \
      --recon gpu --method adaptive,traditional-frameless,late-warp
  done
fi
# The rest of the issue's scaling (new images/s, samples/s and `pass_ms`, the image
# build's steps): 640x480 on 16, 8 and 4 cores, 1280x720 on 8 and 4.
for size in 640x480 1280x720; do
  for n in 16 8 4; do
    [ "$n" -le "$all" ] || continue
    [ "$size/$n" = "1280x720/16" ] && continue
    live "live_${size}_${n}" "$n" --size "$size" --refresh-hz 30 \
      --method adaptive,traditional-frameless
  done
done
# The image build on every core instead of half of them (sampling threads run niced).
if "$bin" live --help 2>/dev/null | grep -q -- '--recon-threads'; then
  for size in 640x480 1280x720; do
    live "live_${size}_${all}_recon${all}" "$all" --size "$size" --refresh-hz 30 \
      --method adaptive --recon-threads "$all"
  done
fi
for size in 1280x720 1920x1080; do
  live "live_${size}_gpurecon" "$all" --size "$size" --refresh-hz 30 --method adaptive --recon gpu
done
if [ -x "$ex" ]; then
  step live_recon 60 bash -c "for t in 1 8; do for m in carried still; do
    echo \"$(case_of '1280 720 4e6 30') 2spp \$m threads=\$t:\"; RAYON_NUM_THREADS=\$t '$ex' $(case_of '1280 720 4e6 30') 2 \$m; done; done"
fi
# The GPU tracer's figures (its issue is resolved; these follow its changes).
if "$bin" bench --help 2>/dev/null | grep -q -- '--trace'; then
  step bench_trace_gpu 90 "$bin" bench --trace gpu --size "$(sz 1920x1080)" --json
fi
if has_trace; then
  live live_1920x1080_gputrace "$all" --size 1920x1080 --refresh-hz 60 --trace gpu \
    --recon gpu --method adaptive,traditional-frameless
fi
for r in 1 2; do
  mkdir -p "$work/view_2cores_recon$r"
  step "view_2cores_recon$r" 20 bash -c "cd '$work/view_2cores_recon$r' && taskset -c 0-1 '$bin' \
    view --headless --size $(sz 1280x720) --refresh-hz 30 --duration 3 --method adaptive \
    --recon-threads $r"
done
step bench_gpu 40 "$bin" bench --recon gpu --json

tar -C "$work" --exclude='*.png' --exclude='ideal-cache' -czf "$out/results.tar.gz" .
echo "done in $((SECONDS - start)) s: $out/results.tar.gz"
