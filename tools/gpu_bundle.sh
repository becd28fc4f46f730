#!/usr/bin/env bash
# Packs this build's GPU checks for a machine that has an NVIDIA driver but
# not Debian's packages (a rented GPU host, a container with the driver
# mounted): the stripped binaries, every shared library they link except
# glibc's own (libc, libm, the loader), which the host's newer glibc serves,
# and a script that runs the GPU suites, the round-trip micro-benchmark
# (read-back against persistent mapped buffers), `sweptccd bench --sweep`
# (batches of 1 to 4,096 pairs: CPU on 1 and on all threads, GPU on all
# threads, and the device descent on all threads, one run), `sweptccd bench --gpu hardware` and `--backend auto` on
# every bundled scene there, and the records of `--backend gpu --threads
# $(nproc)` and of `--backend gpu --device-descent --threads $(nproc)`
# against `--backend cpu --threads 1`, the same sweep on the
# 10.7 M-triangle scene (breakfast+dragons_10M), and the daemon on the CPU
# then the GPU backend (tools/service_bench/backends.sh): 64 clients at 120
# Hz (then also the GPU backend with the device descent, the clients' ready
# pairs in one device batch, docs/SERVICE.md "The device descent"), and 32
# avatars in one room with the shared world on; rooms per GPU
# host (tools/service_bench/capacity.sh with BACKEND=gpu). The GL vendor
# library comes from the host's driver (glvnd's EGL vendor file of NVIDIA,
# found under /usr/local/nvidia or /usr/share/glvnd).
#
#   bash tools/gpu_bundle.sh [BUILD_DIR] [OUT_DIR]   (default build, .gpu)
#
# Then, on the GPU host, from a copy of this tree (data/ included) with
# OUT_DIR beside it: `bash OUT_DIR/run.sh RESULTS_DIR`. docs/GPU.md,
# "On an NVIDIA H200", has what it measured. run.sh keeps within BUDGET
# seconds (default 470: the device machine's limits are 10 minutes a command
# and 15 minutes a session): the parts run in order of importance, each
# under `timeout` of at most what is left, and every part writes its rows as
# it goes, so a part cut short leaves a partial table and "exit 124".
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
out=${2:-.gpu}
rm -rf "$out"
mkdir -p "$out/bin" "$out/lib"
tests="gl_context_test gpu_culler_test backend_calibration_test ccd_random_gpu_test real_data_gpu_test device_descent_test world_environment_gpu_test"
for b in sweptccd sweptccd-service sweptccd_latency_bench sweptccd_ws_latency \
  sweptccd_gpu_roundtrip_bench $tests; do
  strip -o "$out/bin/$b" "$build/bin/$b"
done
# The daemon's benches run in a private network namespace and route
# multicast over its loopback with iproute2's ip, which a GPU host's image
# may lack: this machine's ip travels, used only where the host has none.
mkdir -p "$out/tools"
cp -L "$(command -v ip)" "$out/tools/ip"
ldd "$out"/bin/* "$out"/tools/* | awk '/=>/ { print $3 }' | sort -u |
  grep -v -E '/(libc|libm|ld-linux[^/]*)\.so' | xargs -I{} cp -L {} "$out/lib/"
tar -C "$out" -cJf "$out/lib.tar.xz" lib
sed -n 's/^SWEPTCCD_DATA_DIR:PATH=//p' "$build/CMakeCache.txt" > "$out/data_dir.txt"
rm -rf "$out/lib"
# A walk for `--backend auto` (its calibration is the same for any skeleton
# and scene pair; the walk's records are compared across backends).
"$build/bin/sweptccd" import-bvh --bvh data/mocap/cmu_02_01_walk.bvh.gz --up z --rate 30 \
  --offset 0 0 0.02 --skeleton-out "$out/walk_skel.json" --poses-out "$out/walk_poses.jsonl" \
  > /dev/null
cat > "$out/run.sh" << 'EOF'
#!/usr/bin/env bash
# Runs on the GPU host from the tree's root: bash BUNDLE/run.sh RESULTS_DIR.
set -u
root=$PWD
bundle=$(cd "$(dirname "$0")" && pwd)
results=${1:?usage: run.sh RESULTS_DIR}
mkdir -p "$results"
tar -C "$bundle" -xJf "$bundle/lib.tar.xz"
export LD_LIBRARY_PATH=$bundle/lib
# The tests find the data where this build was configured (SWEPTCCD_DATA_DIR).
data_dir=$(cat "$bundle/data_dir.txt")
if [ -n "$data_dir" ] && [ ! -e "$data_dir" ]; then
  mkdir -p "$(dirname "$data_dir")" && ln -s "$root/data" "$data_dir"
fi
vendor=$(ls /usr/local/nvidia/share/glvnd/egl_vendor.d/*.json \
  /usr/share/glvnd/egl_vendor.d/*.json 2> /dev/null | grep -i nvidia | head -1 || true)
if [ -n "$vendor" ]; then export __EGL_VENDOR_LIBRARY_FILENAMES=$vendor; fi
B=$bundle/bin
if ! command -v ip > /dev/null; then export PATH=$PATH:$bundle/tools; fi
# The time budget: part CAP runs under timeout of min(CAP, what is left).
budget=${BUDGET:-470}
start=$SECONDS
cap() {
  local left=$((budget - (SECONDS - start)))
  if [ "$left" -lt "$1" ]; then echo $((left > 1 ? left : 1)); else echo "$1"; fi
}
part() { echo "== $1 at $((SECONDS - start)) s" >> "$results/times.txt"; }
# PARTS (default: all, in this order) names the parts to run, e.g.
# PARTS="sweep capacity_gpu" for a second, shorter visit; SWEEP_ARGS adds
# options to the sweep's `bench` (e.g. "--scene morse_apartment"); GPU_TESTS
# names the suites of the part `tests` (default: all seven).
want() { [ -z "${PARTS:-}" ] || [[ " $PARTS " == *" $1 "* ]]; }
{
  date -u
  nvidia-smi --query-gpu=name,driver_version --format=csv
  echo "EGL vendor file: ${vendor:-none}; cores $(nproc); budget $budget s"
  ldd "$B/sweptccd" | grep 'not found'
} > "$results/env.txt" 2>&1
# The GPU suites at once (correctness only; they share the GPU).
if want tests; then
  part tests
  t_cap=$(cap 150)
  for t in ${GPU_TESTS:-gl_context_test gpu_culler_test backend_calibration_test \
    device_descent_test ccd_random_gpu_test real_data_gpu_test world_environment_gpu_test}; do
    (
      s=$SECONDS
      timeout "$t_cap" "$B/$t" --gtest_brief=1 > "/tmp/gpu_bundle_$t.log" 2>&1
      echo "== $t exit $? in $((SECONDS - s)) s" >> "/tmp/gpu_bundle_$t.log"
    ) &
  done
  wait
  cat /tmp/gpu_bundle_*_test.log > "$results/tests.txt"
fi
# Batches of pairs (issue 30): pairs/s and latency per batch for the CPU on
# 1 thread, the CPU on every core and the GPU on every core, in one run.
if want sweep; then
  part sweep
  timeout "$(cap 110)" "$B/sweptccd" bench --data "$root/data" --gpu hardware --no-peers --sweep \
    --threads "$(nproc)" ${SWEEP_ARGS:-} --markdown "$results/sweep.md" > "$results/sweep.txt" 2>&1
  echo "exit $?" >> "$results/sweep.txt"
fi
# The daemon, CPU then GPU backend, then the GPU backend with the device
# descent (batches of up to 16 ready pairs, no gather window), same load,
# one run: 64 clients at 120 Hz on the 1.1 M-triangle dragon room, every
# core's worker; each backend's answers against the CPU's.
if want daemon_64x120; then
  part daemon_64x120
  CLIENTS=64 RATE=120 WORKERS=$(nproc) REQUIRE_HARDWARE=1 BACKENDS="cpu gpu gpu-descent" \
    timeout "$(cap 110)" \
    bash tools/service_bench/backends.sh "$bundle" 10 > "$results/daemon_64x120.txt" 2>&1
  echo "exit $?" >> "$results/daemon_64x120.txt"
fi
# 32 avatars in one room with the shared world on, CPU then GPU backend.
if want daemon_32_shared; then
  part daemon_32_shared
  CLIENTS=32 RATE=90 WORKERS=$(nproc) SHARED=true REQUIRE_HARDWARE=1 timeout "$(cap 100)" \
    bash tools/service_bench/backends.sh "$bundle" 10 > "$results/daemon_32_shared.txt" 2>&1
  echo "exit $?" >> "$results/daemon_32_shared.txt"
fi
# The shared world offline (issue 30): 32 avatars and 4 objects in the
# breakfast room (`world-bench --generate-only`), `sweptccd world` on the CPU
# with 1 and every thread, the GPU, and the GPU with the device descent;
# wall time of each and its records against the CPU's on one thread.
if want world_32; then
  part world_32
  {
    w=/tmp/gpu_bundle_world
    "$B/sweptccd" world-bench --data "$root/data" --out "$w" --avatars 32 --generate-only
    for run in "cpu 1" "cpu $(nproc)" "gpu $(nproc)" "gpu $(nproc) --device-descent"; do
      set -- $run
      t0=$(date +%s%N)
      timeout "$(cap 30)" "$B/sweptccd" world --world "$w/world.json" --backend "$1" --threads "$2" \
        ${3:-} --require-hardware --log-level info 2> /tmp/gpu_bundle_world_log |
        sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > "/tmp/gpu_bundle_world_$1_$2${3:-}"
      t1=$(date +%s%N)
      grep -E 'backend|device descent' /tmp/gpu_bundle_world_log | head -3
      echo "world --backend $1 --threads $2 ${3:-}: $(((t1 - t0) / 1000000)) ms wall," \
        "records $(wc -l < "/tmp/gpu_bundle_world_$1_$2${3:-}"), differing from cpu 1:" \
        "$(diff /tmp/gpu_bundle_world_cpu_1 "/tmp/gpu_bundle_world_$1_$2${3:-}" | grep -c '^>')"
    done
  } > "$results/world_32.txt" 2>&1
fi
# One round trip (issue 30): read-back against persistent mapped buffers and
# a fence, 1 to 4,096 capsules, a small scene and the 0.9 M-triangle dragon.
if want roundtrip; then
  part roundtrip
  for e in morse_apartment.ply.gz stanford_dragon_vrip.ply.gz; do
    timeout "$(cap 20)" "$B/sweptccd_gpu_roundtrip_bench" --env "data/env/$e" --seconds 0.3
    echo "exit $?"
  done > "$results/roundtrip.txt" 2>&1
fi
# The sweep on the 10.7 M-triangle scene (twelve dragons and the room;
# built here from the bundled meshes in seconds).
if want sweep_10M; then
  part sweep_10M
  timeout "$(cap 70)" "$B/sweptccd" bench --data "$root/data" --gpu hardware --no-peers --sweep \
    --threads "$(nproc)" --scene breakfast+dragons_10M --clip cmu_02_01_walk.bvh \
    --clip boxing_toes.bvh --max-pairs 300 --markdown "$results/sweep_10M.md" \
    > "$results/sweep_10M.txt" 2>&1
  echo "exit $?" >> "$results/sweep_10M.txt"
fi
# --backend auto on each scene, and the walk's records on both backends.
if want auto; then
  part auto
  for e in morse_apartment.ply.gz bitterli_breakfast_room.ply.gz \
    bitterli_grey_white_room.ply.gz stanford_dragon_vrip.ply.gz; do
    echo "== $e"
    q=("$B/sweptccd" query --skeleton "$bundle/walk_skel.json" --poses "$bundle/walk_poses.jsonl"
      --env "data/env/$e")
    timeout "$(cap 15)" "${q[@]}" --backend auto --output /dev/null 2>&1 | grep 'backend'
    timeout "$(cap 15)" "${q[@]}" --backend cpu --threads 1 2> /dev/null | sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > /tmp/gpu_bundle_cpu
    timeout "$(cap 15)" "${q[@]}" --backend gpu 2> /dev/null | sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > /tmp/gpu_bundle_gpu
    echo "records: cpu $(wc -l < /tmp/gpu_bundle_cpu), gpu $(wc -l < /tmp/gpu_bundle_gpu)," \
      "differing lines $(diff /tmp/gpu_bundle_cpu /tmp/gpu_bundle_gpu | grep -c '^>')"
    # The GPU with every core's worker (requests coalesced), logged dispatches.
    timeout "$(cap 15)" "${q[@]}" --backend gpu --threads "$(nproc)" --log-level info 2> /tmp/gpu_bundle_log |
      sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > /tmp/gpu_bundle_gpu_threads
    grep -E 'dispatches|capsules cross' /tmp/gpu_bundle_log
    echo "records: gpu --threads $(nproc) $(wc -l < /tmp/gpu_bundle_gpu_threads)," \
      "differing lines $(diff /tmp/gpu_bundle_cpu /tmp/gpu_bundle_gpu_threads | grep -c '^>')"
    # The device descent (docs/GPU.md): the chunk's free intervals on the GPU.
    timeout "$(cap 15)" "${q[@]}" --backend gpu --device-descent --threads "$(nproc)" \
      --log-level info 2> /tmp/gpu_bundle_log |
      sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > /tmp/gpu_bundle_gpu_descent
    grep -E 'device descent' /tmp/gpu_bundle_log
    echo "records: gpu --device-descent --threads $(nproc) $(wc -l < /tmp/gpu_bundle_gpu_descent)," \
      "differing lines $(diff /tmp/gpu_bundle_cpu /tmp/gpu_bundle_gpu_descent | grep -c '^>')"
  done > "$results/auto.txt" 2>&1
fi
# Rooms per GPU host (issue 32, docs/DEPLOY.md "Capacity"): 1, 4 and 8
# rooms of the 1.1 M-triangle room at once, each on the GPU backend, 2
# clients x 90 Hz each; memory per room and each room's p99.
if want capacity_gpu; then
  part capacity_gpu
  BACKEND=gpu SCENES= SCALE_SCENES=breakfast+dragon_1.1M ROOMS="1 4 8" SECONDS_PER_RUN=3 \
    READY_S=40 timeout "$(cap 60)" bash tools/service_bench/capacity.sh "$bundle" \
    > "$results/capacity_gpu.txt" 2>&1
  echo "exit $?" >> "$results/capacity_gpu.txt"
fi
# The bench alone: the CPU and GPU backends on the same pairs, wall clock.
if want bench; then
  part bench
  timeout "$(cap 60)" "$B/sweptccd" bench --data "$root/data" --gpu hardware --no-peers --clock wall \
    --markdown "$results/bench.md" > "$results/bench.txt" 2>&1
  echo "exit $?" >> "$results/bench.txt"
fi
if want bench_per_link; then
  part bench_per_link
  timeout "$(cap 40)" "$B/sweptccd" bench --data "$root/data" --gpu hardware --no-peers --clock wall \
    --scene breakfast+dragon_1.1M --per-link > "$results/bench_per_link.txt" 2>&1
  echo "exit $?" >> "$results/bench_per_link.txt"
fi
part "done"
EOF
chmod +x "$out/run.sh"
du -sh "$out"
