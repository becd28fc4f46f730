#!/usr/bin/env python3
"""A strict reader of the Prometheus text exposition format 0.0.4 for tests:
HELP then TYPE before each family's samples, one block per family, label
syntax and escapes, counters named *_total, histogram buckets increasing in
le and count with +Inf equal to _count. Prints the samples as JSON
{"name{labels}": value} on success; exits 1 naming the first problem.
   prom_parse.py < metrics.txt"""
import json
import math
import re
import sys

NAME = r"[a-zA-Z_:][a-zA-Z0-9_:]*"
LABEL = r'[a-zA-Z_][a-zA-Z0-9_]*="(?:[^"\\\n]|\\[\\"n])*"'
SAMPLE = re.compile(r"(%s)(\{%s(?:,%s)*\})? (\S+)$" % (NAME, LABEL, LABEL))


def fail(msg):
    print("prom_parse: " + msg, file=sys.stderr)
    sys.exit(1)


def value(s):
    if s in ("+Inf", "-Inf", "NaN"):
        return {"+Inf": math.inf, "-Inf": -math.inf, "NaN": math.nan}[s]
    try:
        return float(s)
    except ValueError:
        fail("bad value " + s)


text = sys.stdin.read()
if not text.endswith("\n"):
    fail("no final newline")
types, samples, done, current = {}, {}, set(), None
buckets = {}
for line in text.splitlines():
    m = re.match(r"# HELP (%s) (.*)$" % NAME, line)
    if m:
        if m[1] in done or m[1] == current:
            fail("family twice: " + line)
        if current:
            done.add(current)
        current = m[1]
        continue
    m = re.match(r"# TYPE (%s) (counter|gauge|histogram)$" % NAME, line)
    if m:
        if m[1] != current or m[1] in types:
            fail("TYPE out of place: " + line)
        if m[2] == "counter" and not m[1].endswith("_total"):
            fail("counter not named _total: " + line)
        types[m[1]] = m[2]
        continue
    m = SAMPLE.match(line)
    if not m:
        fail("not exposition format: %r" % line)
    name, labels, v = m[1], m[2] or "", value(m[3])
    family = name
    for suffix in ("_bucket", "_sum", "_count"):
        if name.endswith(suffix) and types.get(name[: -len(suffix)]) == "histogram":
            family = name[: -len(suffix)]
    if family != current or family not in types:
        fail("sample outside its family: " + line)
    if name + labels in samples:
        fail("sample twice: " + line)
    samples[name + labels] = v
    if name.endswith("_bucket") and family != name:
        le = re.search(r'le="([^"]*)"', labels)
        if not le:
            fail("bucket without le: " + line)
        key = (family, re.sub(r',?le="[^"]*"', "", labels))
        buckets.setdefault(key, []).append((value(le[1]), v))
for (family, labels), bs in buckets.items():
    if [b[0] for b in bs] != sorted(b[0] for b in bs) or bs[-1][0] != math.inf:
        fail("buckets of %s%s not increasing to +Inf" % (family, labels))
    if any(b[1] > c[1] for b, c in zip(bs, bs[1:])):
        fail("bucket counts of %s%s decrease" % (family, labels))
    lbl = labels.replace("{}", "").replace("{,", "{")
    if samples.get(family + "_count" + lbl) != bs[-1][1]:
        fail("%s: +Inf bucket != _count" % family)
print(json.dumps(samples))
