#!/usr/bin/env bash
# Packaging.InstallAndFindPackage: `cmake --install` puts the daemon, the
# tool, the exported libraries, their headers, the generated message headers,
# the CMake package, sweptccd.pc, the systemd unit, the example configuration
# and the Java jar under a temporary prefix; a small consumer project
# (tests/packaging/consumer, copied out of the tree) is built against that
# prefix with find_package(SweptCCD CONFIG REQUIRED), and its source again
# with pkg-config, and both run (sign, verify, decode, memq:// round trip).
#   install_consumer_test.sh SOURCE_DIR BUILD_DIR WORK_DIR CXX [CXXFLAGS]
# (CXXFLAGS: the sanitizer flags when the libraries were built with them)
set -euo pipefail
src=$1 build=$2 work=$3 cxx=$4 cxxflags=${5:-}
fail() { echo "install_consumer_test: $*" >&2; exit 1; }
command -v pkg-config >/dev/null || fail "no pkg-config: install Debian package pkg-config"
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" > "$work/install.log" ||
  { cat "$work/install.log" >&2; fail "cmake --install failed"; }

# What must be there. The generated headers: one per msgs/*.lcm.
expect=(bin/sweptccd-service bin/sweptccd
        lib/libsweptccd_msgs.a lib/libsweptccd_errors.a
        include/sweptccd/msgs/signing.h include/sweptccd/msgs/checked_decode.h
        include/sweptccd/msgs/text.h include/sweptccd/msgs/channels.h
        include/sweptccd/core/errors.h
        lib/cmake/SweptCCD/SweptCCDConfig.cmake lib/cmake/SweptCCD/SweptCCDConfigVersion.cmake
        lib/cmake/SweptCCD/SweptCCDTargets.cmake lib/pkgconfig/sweptccd.pc
        lib/systemd/system/sweptccd-service.service
        share/doc/sweptccd/examples/sweptccd.yaml
        share/doc/sweptccd/examples/sweptccd-service-gpu.conf
        share/java/sweptccd_msgs.jar)
for f in "$src"/msgs/*.lcm; do expect+=("include/sweptccd/sweptccd/$(basename "$f" .lcm).hpp"); done
[ -f "$prefix/share/java/sweptccd_msgs.jar" ] || fail "not installed: share/java/sweptccd_msgs.jar" \
  "(built only when Debian packages default-jdk-headless and liblcm-java were installed at configure time)"
for f in "${expect[@]}"; do [ -f "$prefix/$f" ] || fail "not installed: $f"; done
# The installed unit starts the installed daemon.
grep -qx "ExecStart=$prefix/bin/sweptccd-service --config /etc/sweptccd/sweptccd.yaml --backend cpu" \
  "$prefix/lib/systemd/system/sweptccd-service.service" || fail "unit's ExecStart is not the installed daemon"
# Nothing installed points back into the source or build tree.
if grep -rlF -e "$src/" -e "$build/" "$prefix/lib/cmake" "$prefix/lib/pkgconfig"; then
  fail "the installed package names the source or build tree (above)"
fi
"$prefix/bin/sweptccd-service" --help > "$work/help.txt" || fail "installed daemon --help failed"
grep -q -- '--config' "$work/help.txt" || fail "installed daemon --help says nothing of --config"

# The consumer, outside the tree, through find_package.
cp -r "$src/tests/packaging/consumer" "$work/consumer"
cmake -S "$work/consumer" -B "$work/consumer-build" -DCMAKE_PREFIX_PATH="$prefix" \
      -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS="$cxxflags" \
      > "$work/consumer-cmake.log" 2>&1 ||
  { cat "$work/consumer-cmake.log" >&2; fail "consumer: cmake (find_package) failed"; }
grep -q "SweptCCD_DIR:PATH=$prefix/lib/cmake/SweptCCD" "$work/consumer-build/CMakeCache.txt" ||
  fail "find_package found SweptCCD elsewhere than $prefix"
cmake --build "$work/consumer-build" > "$work/consumer-build.log" 2>&1 ||
  { cat "$work/consumer-build.log" >&2; fail "consumer: build with find_package failed"; }
"$work/consumer-build/consumer" || fail "consumer (find_package) failed"

# The same source through pkg-config.
export PKG_CONFIG_PATH=$prefix/lib/pkgconfig
[ "$(pkg-config --modversion sweptccd)" = "$(sed -n 's/^Version: //p' "$prefix/lib/pkgconfig/sweptccd.pc")" ] ||
  fail "pkg-config does not read sweptccd.pc"
flags=$(pkg-config --cflags --libs sweptccd) || fail "pkg-config --cflags --libs sweptccd failed"
echo "pkg-config sweptccd: $flags"
# shellcheck disable=SC2086  # word splitting of the flags is wanted
"$cxx" -std=c++17 -O1 $cxxflags "$work/consumer/consumer.cc" -o "$work/consumer-pc" $flags ||
  fail "consumer: build with pkg-config failed"
"$work/consumer-pc" || fail "consumer (pkg-config) failed"
echo "install_consumer_test: passed"
