#!/usr/bin/env bash
# Packs this build's GPU checks for a machine that has an NVIDIA driver but
# not Debian's packages (a rented GPU host, a container with the driver
# mounted): the stripped binaries, every shared library they link except
# glibc's own (libc, libm, the loader), which the host's newer glibc serves,
# and a script that runs the GPU suites, the round-trip micro-benchmark
# (read-back against persistent mapped buffers), `sweptccd bench --sweep`
# (batches of 1 to 4,096 pairs: CPU on 1 and on all threads, GPU on all
# threads, one run), `sweptccd bench --gpu hardware` and `--backend auto` on
# every bundled scene there, and the records of `--backend gpu --threads
# $(nproc)` against `--backend cpu --threads 1`. The GL vendor library comes
# from the host's driver (glvnd's EGL vendor file of NVIDIA, found under
# /usr/local/nvidia or /usr/share/glvnd).
#
#   bash tools/gpu_bundle.sh [BUILD_DIR] [OUT_DIR]   (default build, .gpu)
#
# Then, on the GPU host, from a copy of this tree (data/ included) with
# OUT_DIR beside it: `bash OUT_DIR/run.sh RESULTS_DIR`. docs/GPU.md,
# "On an NVIDIA H200", has what it measured.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
out=${2:-.gpu}
rm -rf "$out"
mkdir -p "$out/bin" "$out/lib"
tests="gl_context_test gpu_culler_test backend_calibration_test ccd_random_gpu_test real_data_gpu_test"
for b in sweptccd sweptccd_gpu_roundtrip_bench $tests; do
  strip -o "$out/bin/$b" "$build/bin/$b"
done
ldd "$out"/bin/* | awk '/=>/ { print $3 }' | sort -u |
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
{
  date -u
  nvidia-smi --query-gpu=name,driver_version --format=csv
  echo "EGL vendor file: ${vendor:-none}; cores $(nproc)"
  ldd "$B/sweptccd" | grep 'not found'
} > "$results/env.txt" 2>&1
# The GPU suites at once (correctness only; they share the GPU).
for t in gl_context_test gpu_culler_test backend_calibration_test ccd_random_gpu_test \
  real_data_gpu_test; do
  (
    s=$SECONDS
    timeout 220 "$B/$t" --gtest_brief=1 > "/tmp/gpu_bundle_$t.log" 2>&1
    echo "== $t exit $? in $((SECONDS - s)) s" >> "/tmp/gpu_bundle_$t.log"
  ) &
done
wait
cat /tmp/gpu_bundle_*_test.log > "$results/tests.txt"
# One round trip (issue 30): read-back against persistent mapped buffers and
# a fence, 1 to 4,096 capsules, a small scene and the 0.9 M-triangle dragon.
for e in morse_apartment.ply.gz stanford_dragon_vrip.ply.gz; do
  timeout 60 "$B/sweptccd_gpu_roundtrip_bench" --env "data/env/$e" --seconds 0.3
  echo "exit $?"
done > "$results/roundtrip.txt" 2>&1
# Batches of pairs (issue 30): pairs/s and latency per batch for the CPU on
# 1 thread, the CPU on every core and the GPU on every core, in one run.
timeout 240 "$B/sweptccd" bench --data "$root/data" --gpu hardware --no-peers --sweep \
  --threads "$(nproc)" --markdown "$results/sweep.md" > "$results/sweep.txt" 2>&1
echo "exit $?" >> "$results/sweep.txt"
# The bench alone: the CPU and GPU backends on the same pairs, wall clock.
timeout 150 "$B/sweptccd" bench --data "$root/data" --gpu hardware --no-peers --clock wall \
  --markdown "$results/bench.md" > "$results/bench.txt" 2>&1
echo "exit $?" >> "$results/bench.txt"
timeout 80 "$B/sweptccd" bench --data "$root/data" --gpu hardware --no-peers --clock wall \
  --scene breakfast+dragon_1.1M --per-link > "$results/bench_per_link.txt" 2>&1
echo "exit $?" >> "$results/bench_per_link.txt"
# --backend auto on each scene, and the walk's records on both backends.
for e in morse_apartment.ply.gz bitterli_breakfast_room.ply.gz \
  bitterli_grey_white_room.ply.gz stanford_dragon_vrip.ply.gz; do
  echo "== $e"
  q=("$B/sweptccd" query --skeleton "$bundle/walk_skel.json" --poses "$bundle/walk_poses.jsonl"
    --env "data/env/$e")
  timeout 40 "${q[@]}" --backend auto --output /dev/null 2>&1 | grep 'backend'
  timeout 40 "${q[@]}" --backend cpu --threads 1 2> /dev/null | sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > /tmp/gpu_bundle_cpu
  timeout 40 "${q[@]}" --backend gpu 2> /dev/null | sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > /tmp/gpu_bundle_gpu
  echo "records: cpu $(wc -l < /tmp/gpu_bundle_cpu), gpu $(wc -l < /tmp/gpu_bundle_gpu)," \
    "differing lines $(diff /tmp/gpu_bundle_cpu /tmp/gpu_bundle_gpu | grep -c '^>')"
  # The GPU with every core's worker (requests coalesced), logged dispatches.
  timeout 40 "${q[@]}" --backend gpu --threads "$(nproc)" --log-level info 2> /tmp/gpu_bundle_log |
    sed -E 's/"elapsed_us":[^,]*,//; s/"stats":\{[^}]*\},//' > /tmp/gpu_bundle_gpu_threads
  grep -E 'dispatches|capsules cross' /tmp/gpu_bundle_log
  echo "records: gpu --threads $(nproc) $(wc -l < /tmp/gpu_bundle_gpu_threads)," \
    "differing lines $(diff /tmp/gpu_bundle_cpu /tmp/gpu_bundle_gpu_threads | grep -c '^>')"
done > "$results/auto.txt" 2>&1
EOF
chmod +x "$out/run.sh"
du -sh "$out"
