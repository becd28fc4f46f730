#!/usr/bin/env python3
"""A fake systemd NOTIFY_SOCKET for tests: binds a unix datagram socket at
PATH and appends every datagram's lines to LOG as "SECONDS LINE" (seconds
since start).   notify_socket.py PATH LOG"""
import socket
import sys
import time

path, log = sys.argv[1], sys.argv[2]
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(path)
start = time.monotonic()
while True:
    data = s.recv(4096).decode(errors="replace")
    with open(log, "a") as f:
        for line in data.splitlines():
            f.write("%.4f %s\n" % (time.monotonic() - start, line))
