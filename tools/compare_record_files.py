#!/usr/bin/env python3
"""Compares record files written by two sweptccd binaries, for
tools/compare_records.sh and tools/compare_records_full_body.sh: every
OLD.old.jsonl matched by GLOB against its OLD.new.jsonl, record by record,
all fields but elapsed_us and stats. Prints the first five differing records
and one summary line; exit status 1 when any record differs.

  compare_record_files.py GLOB LABEL [--undecided] [--full-paths]
"""
import glob
import json
import os
import sys


def main():
    pattern, label = sys.argv[1], sys.argv[2]
    show_undecided = "--undecided" in sys.argv[3:]
    name = (lambda p: p) if "--full-paths" in sys.argv[3:] else os.path.basename
    total = differing = contact = undecided = 0
    for old in sorted(glob.glob(pattern)):
        new = old[: -len(".old.jsonl")] + ".new.jsonl"
        a = [json.loads(l) for l in open(old) if l.strip()]
        b = [json.loads(l) for l in open(new) if l.strip()] if os.path.exists(new) else []
        if len(a) != len(b):
            print(f"{name(old)}: {len(a)} records before, {len(b)} after")
            differing += abs(len(a) - len(b))
        for x, y in zip(a, b):
            for r in (x, y):
                r.pop("elapsed_us", None)
                r.pop("stats", None)
            total += 1
            contact += x.get("result") == "contact"
            undecided += bool(x.get("undecided"))
            if x != y:
                differing += 1
                if differing <= 5:
                    print(f"{name(old)} pair {x.get('pair')}: differs\n  old {x}\n  new {y}")
    counts = f"contact: {contact}" + (f", undecided: {undecided}" if show_undecided else "")
    print(f"{label} compared: {total} ({counts}), differing: {differing}")
    sys.exit(1 if differing else 0)


if __name__ == "__main__":
    main()
