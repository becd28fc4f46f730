#!/usr/bin/env bash
# Packaging.JavaDecodesEveryType: the Java classes of the message types
# (build/msgs/sweptccd_msgs.jar) decode what the C++ side publishes, as
# lcm-spy would. lcm_log_writer writes one message of every type to an LCM
# log through the C++ LCM API and the file:// provider (no network);
# DecodeLog.java, compiled here against lcm.jar and the jar, reads the log
# with lcm.logging.Log and checks every message (see its header).
# The types are the msgs/*.lcm files: a new .lcm file is covered once it is in
# SWEPTCCD_LCM_TYPES (msgs/CMakeLists.txt) and has a Fill() overload in
# tests/packaging/lcm_log_writer.cc; until then this test fails naming it.
#   java_decode_test.sh SOURCE_DIR LCM_LOG_WRITER MSGS_JAR WORK_DIR
set -euo pipefail
src=$1 writer=$2 jar=$3 work=$4
lcm_jar=${LCM_JAVA_JAR:-/usr/share/java/lcm.jar}
fail() { echo "java_decode_test: $*" >&2; exit 1; }
command -v javac >/dev/null || fail "no javac: install Debian package default-jdk-headless"
command -v java >/dev/null || fail "no java: install Debian package default-jdk-headless"
command -v jar >/dev/null || fail "no jar: install Debian package default-jdk-headless"
[ -f "$lcm_jar" ] || fail "no $lcm_jar: install Debian package liblcm-java"
[ -f "$jar" ] || fail "no $jar: it is built when javac (default-jdk-headless) and lcm.jar (liblcm-java) are installed at configure time; install them, re-run cmake and build"

rm -rf "$work"
mkdir -p "$work/classes"
types=()
for f in "$src"/msgs/*.lcm; do types+=("$(basename "$f" .lcm)"); done
[ ${#types[@]} -gt 0 ] || fail "no msgs/*.lcm"
echo "types: ${types[*]}"
# Every type is in the jar (class sweptccd/<type>.class).
listing=$(jar tf "$jar") || fail "jar tf $jar failed"
for t in "${types[@]}"; do
  grep -qx "sweptccd/$t.class" <<< "$listing" ||
    fail "sweptccd_msgs.jar lacks sweptccd/$t.class: add $t to SWEPTCCD_LCM_TYPES in msgs/CMakeLists.txt"
done

"$writer" "file://$work/all_types.lcmlog?mode=w" "$work/manifest.txt"
[ -s "$work/all_types.lcmlog" ] || fail "lcm_log_writer wrote no log"
javac -nowarn -d "$work/classes" -cp "$lcm_jar" "$src/tests/packaging/DecodeLog.java"
# The jar reaches the type lookup as it reaches lcm-spy: through CLASSPATH
# (lcm-spy's own -cp is lcm.jar; docs/USAGE.md "Install and use from your project").
# LCMTypeDatabase scans the whole class path, lcm.jar's lcm-spy GUI classes
# included, which need jchart2d (not needed here): drop those notices.
rc=0
CLASSPATH="$jar" java -Djava.awt.headless=true -cp "$lcm_jar:$work/classes" DecodeLog \
  "$work/all_types.lcmlog" "$work/manifest.txt" "${types[@]}" > "$work/decode.log" 2>&1 || rc=$?
grep -v -e '^ClassDiscoverer: java.lang.NoClassDefFoundError: info/monitorenter/' \
        -e '^ *jar: .*/lcm.jar$' -e '^ *class: lcm/spy/' "$work/decode.log" || true
[ "$rc" -eq 0 ] || fail "DecodeLog failed (exit $rc)"
echo "java_decode_test: passed"
