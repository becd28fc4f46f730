#!/usr/bin/env bash
# The whole project and its test suite under AddressSanitizer (with
# LeakSanitizer) and UndefinedBehaviorSanitizer: builds into build-asan/
# (-O1 -g, -fno-sanitize-recover=undefined, so any UB fails the test that hit
# it) and runs ctest there. Exit status: ctest's (non-zero on any finding).
#   tools/sanitize.sh [extra ctest arguments]
# Environment: SWEPTCCD_ASAN_BUILD (build folder, default build-asan),
# CC/CXX (default: the system gcc), JOBS (default 2).
#
# What runs: every ctest test except the ones named by `exclude` below: the
# GPU ones on Mesa's llvmpipe, the end-to-end ones inside their private
# network namespaces (the sanitizer options below are inherited by the daemon
# and the tools they start). SANITIZE_ALL=1 runs everything.
#
# Excluded, and why: the seeded randomized engine-against-twin comparisons
# (CcdRandomTest, CPU and Gpu.) and the real-scene sweeps (RealDataTest, CPU
# and Gpu.). They are 213 of the suite's 285 CPU-seconds in the Release build,
# and at -O1 with ASan, UBSan and Eigen's assertions the engine runs 15 to
# 100 times slower (measured on the shared 2-core machine: motion_test
# 2.1 s -> 209 s, mesh_test 3.7 s -> 167 s, loaded), so with them the suite
# would not fit CI's cap. They run unsanitized in the main ctest; the code
# they exercise (engine, BVH, distance, GPU culler) runs sanitized here
# through the bvh, distance, swept-bound, GPU-culler, query, service and
# end-to-end tests.
set -euo pipefail
cd "$(dirname "$0")/.."
src=$PWD
build=${SWEPTCCD_ASAN_BUILD:-build-asan}
jobs=${JOBS:-2}
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache); fi

cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Sanitize -DSWEPTCCD_SANITIZE=ON \
  -DCMAKE_CXX_FLAGS_SANITIZE="-O1 -g" -DCMAKE_C_FLAGS_SANITIZE="-O1 -g" \
  "${launcher[@]}" >/dev/null
cmake --build "$build" -j"$jobs"

# halt_on_error/abort: the first finding ends the process with a report;
# detect_leaks: LSan at exit. The suppressions file lists third-party
# libraries only (Mesa's drivers and LLVM, GLVND): never our code.
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:detect_stack_use_after_return=0:strict_string_checks=1:check_initialization_order=1:detect_odr_violation=1"
export LSAN_OPTIONS="suppressions=$src/tools/lsan_suppressions.txt:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
# Findings, open (CI's .ci/run runs the suites verified clean until fixed):
#  - LcmTransportTest.{PosesInContactEventsOut,UndecodableMessagesAreRejectedNotFatal,
#    RejectionsAndStatusGoOutOnTheirChannels}: UBSan "member access within
#    address ... which does not point to an object of type
#    LCMMHUntypedSubscription" in LCM's cb_func (lcm-cpp-impl.hpp:108) while
#    the test pumps memq://: a subscription pointer that no longer points to
#    its object (a stale subscription of a transport, or LCM's own).
#  - ServiceEndToEnd.BadInputRejectedGoodClientUnaffected: LeakSanitizer,
#    2 x 128 bytes realloc'd inside the sweptccd binary (no symbols past the
#    allocator).
#  - Not yet run through under the sanitizers on the shared machine (time):
#    BvhTest (31 of its tests passed, SeparationMatchesBruteForceOverAllTriangles
#    and QueryNeverCullsATouchingLink did not finish in the time there was),
#    Query/RenderCommandTest, Gpu.* (culler, context), the other
#    ServiceEndToEnd tests, Demo.
exclude='^(Gpu\.)?(CcdRandomTest|RealDataTest)\.'
if [ "${SANITIZE_ALL:-0}" = 1 ]; then exclude='^$'; fi
ctest --test-dir "$build" --output-on-failure -j"$jobs" -E "$exclude" "$@"
