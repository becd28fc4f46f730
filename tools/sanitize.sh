#!/usr/bin/env bash
# The whole project and its test suite under AddressSanitizer (with
# LeakSanitizer) and UndefinedBehaviorSanitizer: builds into build-asan/
# (-O1 -g, -fno-sanitize-recover=undefined, so any UB fails the test that hit
# it) and runs ctest there. Exit status: ctest's (non-zero on any finding).
#   tools/sanitize.sh [extra ctest arguments]
# Environment: SWEPTCCD_ASAN_BUILD (build folder, default build-asan),
# CC/CXX (default: the system gcc), JOBS (default 2), SANITIZE_TARGETS (the
# CMake targets to build, space-separated; default: all). CI builds only the
# test binaries of the suites it runs (.ci/run): the ASan/UBSan build of
# everything (render, GPU, every test binary) at -O1 on 2 shared cores is most
# of the step's cap. ctest lists no test of a binary not built (gtest
# discovery runs at build time), so -R must name suites of built targets.
#
# What runs: every ctest test of the targets built (-R narrows it): the GPU
# ones on Mesa's llvmpipe, the end-to-end ones inside their private network
# namespaces (the sanitizer options below are inherited by the daemon and
# the tools they start). SANITIZE_ALL=1 runs the long suites whole too.
#
# The seeded randomized engine-against-twin comparisons (CcdRandomTest, CPU
# and Gpu.), the real-scene sweeps (RealDataTest) and the BVH suites run
# scaled: SWEPTCCD_TEST_SCALE (default here 0.05; tests/common/test_scale.h)
# runs the first 5% of each suite's seeds and every 20th real-data pair, the
# same cases as the full run, which the main ctest runs unsanitized. At -O1
# with ASan, UBSan and Eigen's assertions the engine runs 15 to 100 times
# slower (measured on the shared 2-core machine: motion_test 2.1 s -> 209 s,
# mesh_test 3.7 s -> 167 s, loaded), so the whole of them would not fit CI's
# cap; scaled, the engine, BVH and real-scene code they exercise runs
# sanitized on real cases.
set -euo pipefail
cd "$(dirname "$0")/.."
src=$PWD
build=${SWEPTCCD_ASAN_BUILD:-build-asan}
jobs=${JOBS:-2}
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

cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Sanitize -DSWEPTCCD_SANITIZE=ON \
  -DCMAKE_CXX_FLAGS_SANITIZE="-O1 -g" -DCMAKE_C_FLAGS_SANITIZE="-O1 -g" \
  "${launcher[@]}" >/dev/null
if [ -n "${SANITIZE_TARGETS:-}" ]; then
  # shellcheck disable=SC2086
  cmake --build "$build" -j"$jobs" --target $SANITIZE_TARGETS
else
  cmake --build "$build" -j"$jobs"
fi

# halt_on_error/abort: the first finding ends the process with a report;
# detect_leaks: LSan at exit. The suppressions file lists third-party
# libraries only (Mesa's drivers and LLVM, GLVND): never our code.
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:detect_stack_use_after_return=0:strict_string_checks=1:check_initialization_order=1:detect_odr_violation=1"
export LSAN_OPTIONS="suppressions=$src/tools/lsan_suppressions.txt:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
# Findings:
#  - Fixed 2026-11-24: every LCM delivery died under UBSan in LCM's cb_func
#    (lcm-cpp-impl.hpp:88 and :108, "object has invalid vptr", then SIGSEGV).
#    Not LCM: GCC 12's -fsanitize=vptr miscompiles a call through a pointer to
#    member function held by a polymorphic object, which is what LCM's
#    subscription callbacks do (tests/tools/gcc_vptr_pmf_repro.cc shows it in
#    30 lines, no LCM). Sanitizer builds with GCC now pass -fno-sanitize=vptr
#    (CMakeLists.txt); LcmTransport*, DaemonTest and LiveSessionTest run clean.
#  - Fixed 2026-11-24: ServiceEndToEnd.BadInputRejectedGoodClientUnaffected
#    reported LeakSanitizer "128 bytes from <unknown module>" in every process
#    that had started a GPU context (the CLI's query, the daemon): Mesa's, not
#    ours. The EGL vendor library dlcloses the driver at eglTerminate, and a
#    block the driver's globals pointed to then looks leaked from a module
#    LSan cannot name (preloading swrast_dri.so made it disappear). Sanitizer
#    builds keep the drivers mapped (core/gpu/gl_context.cc); all end-to-end
#    scripts then passed under ASan/UBSan (CI's step sanitizers-e2e).
export SWEPTCCD_TEST_SCALE=${SWEPTCCD_TEST_SCALE:-0.05}
if [ "${SANITIZE_ALL:-0}" = 1 ]; then export SWEPTCCD_TEST_SCALE=1; fi
echo "sanitize.sh: SWEPTCCD_TEST_SCALE=$SWEPTCCD_TEST_SCALE"
ctest --test-dir "$build" --output-on-failure -j"$jobs" "$@"
