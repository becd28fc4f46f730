#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz with clang into build-fuzz/
# (the project's libraries with -fsanitize=fuzzer-no-link,address,undefined)
# and runs each for a bounded time on a fresh copy of its committed corpus
# (tests/fuzz/corpus/<target>/, which holds every known attack case).
# Exits non-zero when any target crashes, leaks, hangs past -timeout or
# allocates past -rss_limit_mb; the reproducer is left in
# build-fuzz/artifacts/<target>/ (add it to the corpus under a name that
# says what it is once the bug is fixed).
#   tools/fuzz.sh [TARGET...]        (default: every target below)
# Environment: FUZZ_SECONDS (per target, default 30), JOBS (build, default 2),
# FUZZ_SEED (libFuzzer's -seed, default 1: a run is reproducible up to where
# its time cap cuts it; set FUZZ_SEED=0 for a random seed when hunting),
# FUZZ_PLAIN=1: a hunt, not CI: builds into build-fuzz-plain without ASan and
# UBSan (coverage only) and runs under glibc's heap checks
# (libc_malloc_debug.so with glibc.malloc.check=3, perturb=165), which catch
# heap damage inside libraries that are not instrumented (assimp's mesh
# parsing, docs/SECURITY.md) at the next free, where ASan sees it late or
# not at all. Replay a finding under valgrind to see the faulty write.
set -euo pipefail
cd "$(dirname "$0")/.."
src=$PWD
build=build-fuzz
plain=${FUZZ_PLAIN:-0}
plain_flag=OFF
if [ "$plain" = 1 ]; then build=build-fuzz-plain plain_flag=ON; fi
seconds=${FUZZ_SECONDS:-30}
seed=${FUZZ_SEED:-1}
jobs=${JOBS:-2}

# Every parser of outside input.
parsers=(fuzz_skeleton fuzz_pose fuzz_joint_frame fuzz_filter fuzz_config fuzz_world
         fuzz_mesh_obj fuzz_mesh_ply fuzz_mesh_stl fuzz_websocket)
# The LCM message types that cross the wire, each decoded as the daemon and
# the tools decode it: msgs/'s DecodeChecked<T> with the default WireLimits,
# and the raw datagram through VerifyEncoded (tests/fuzz/decode_fuzzer.cc).
# Their corpora hold the attacks lcm-gen's own decoders fall to (client_id and
# reason length INT32_MIN, 2^26 links or contacts, 2^24 clients).
decoders=(fuzz_decode_tracker_pose_t fuzz_decode_status_t fuzz_decode_rejection_t
          fuzz_decode_contact_event_t fuzz_decode_join_request_t fuzz_decode_join_reply_t
          fuzz_decode_leave_t fuzz_decode_object_pose_t fuzz_decode_shared_contact_t)
# 1: the decoder targets run by default (in CI). Set since Decode() calls
# DecodeChecked; before that lcm-gen's decoders failed in seconds.
decoders_checked=1
targets=("${parsers[@]}")
if [ "$decoders_checked" = 1 ]; then targets+=("${decoders[@]}"); fi
build_targets=("${parsers[@]}" "${decoders[@]}")
if [ $# -gt 0 ]; then targets=("$@") build_targets=("$@"); fi

launcher=()
# ccache with paths taken relative to the checkout, so a clone in another
# folder (CI's) reuses what an earlier build of the same sources compiled.
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD}
  # These builds carry debug information (-g), and ccache then hashes the
  # working folder by default (hash_dir), so no other clone ever hit: CI's
  # clean clone recompiled every sanitizer and fuzzer object. Off here: a hit
  # keeps the first clone's folder in its debug information (file and line
  # in a sanitizer's report stay right).
  export CCACHE_NOHASHDIR=${CCACHE_NOHASHDIR:-1}
fi
CC=clang CXX=clang++ cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DSWEPTCCD_FUZZ=ON -DSWEPTCCD_FUZZ_PLAIN="$plain_flag" -DSWEPTCCD_BUILD_TESTS=OFF \
  "${launcher[@]}" >/dev/null
cmake --build "$build" -j"$jobs" --target "${build_targets[@]}"
if [ $# = 0 ] && [ "$decoders_checked" != 1 ]; then
  echo "fuzz.sh: NOT RUN until msgs/ decodes with DecodeChecked: ${decoders[*]}" >&2
fi

# Seeds a target cannot pass until another branch's fix is merged: one
# "target/file  why" a line in tests/fuzz/pending_fixes.txt. They are left out
# of the run and named below, never silently; remove the line with the fix.
pending=tests/fuzz/pending_fixes.txt
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:allocator_may_return_null=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$src/tools/lsan_suppressions.txt:print_suppressions=0"
# Plain: glibc >= 2.34 checks the heap only with its debug malloc preloaded.
run_env=()
if [ "$plain" = 1 ]; then
  run_env=(env LD_PRELOAD=libc_malloc_debug.so.0
           GLIBC_TUNABLES=glibc.malloc.check=3:glibc.malloc.perturb=165)
fi
failed=()
for t in "${targets[@]}"; do
  work=$build/corpus-run/$t
  artifacts=$build/artifacts/$t
  rm -rf "$work" "$artifacts"
  mkdir -p "$work" "$artifacts"
  cp tests/fuzz/corpus/"$t"/* "$work"/
  if [ -f "$pending" ]; then
    while read -r entry why; do
      case "$entry" in "$t"/*)
        echo "fuzz.sh: $entry left out until fixed: $why" >&2
        rm -f "$work/${entry#"$t"/}" ;;
      esac
    done < <(grep -v '^#' "$pending" | grep -v '^[[:space:]]*$')
  fi
  echo "== $t: ${seconds} s on $(ls "$work" | wc -l) seeds"
  status=0
  # -malloc_limit_mb: no input of at most 64 KiB (the largest seed) may ask
  # for one block of 512 MiB; that is an amplification bug (the decoders'
  # counts, a mesh header's element count), not a big input.
  "${run_env[@]}" "$build/bin/$t" -seed="$seed" -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=512 -timeout=10 \
    -close_fd_mask=1 -print_final_stats=1 -artifact_prefix="$artifacts/" "$work" \
    > "$build/$t.log" 2>&1 || status=$?
  grep -E '^(stat::number_of_executed_units|stat::peak_rss_mb)' "$build/$t.log" | tr '\n' ' ' || true
  echo
  if [ "$status" != 0 ]; then
    echo "fuzz.sh: $t FAILED (status $status); reproducer(s): $(ls "$artifacts")" >&2
    grep -E -A20 '^==[0-9]+==ERROR|runtime error|deadly signal|out-of-memory|timeout' "$build/$t.log" | head -40 >&2 || true
    failed+=("$t")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: findings in ${failed[*]} (logs: $build/<target>.log)" >&2
  exit 1
fi
echo "fuzz.sh: ${#targets[@]} targets, ${seconds} s each, no findings"
