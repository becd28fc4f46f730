#!/usr/bin/env python3
"""UDP datagrams across the test router (e2e_failover.sh).
  udp_probe.py send LOCAL_ADDR DEST PORT COUNT     (multicast TTL 8, out of LOCAL_ADDR's link)
  udp_probe.py recv LOCAL_ADDR GROUP_OR_ADDR PORT SECONDS   prints how many arrived
"""
import socket
import struct
import sys
import time

mode, local, dest, port = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
multicast = 224 <= int(dest.split(".")[0]) <= 239
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
if mode == "send":
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 8)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(local))
    for _ in range(int(sys.argv[5])):
        s.sendto(b"probe", (dest, port))
        time.sleep(0.01)
else:
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.bind((dest if multicast else local, port))
    if multicast:
        s.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                     struct.pack("4s4s", socket.inet_aton(dest), socket.inet_aton(local)))
    s.settimeout(0.1)
    end, n = time.monotonic() + float(sys.argv[5]), 0
    while time.monotonic() < end:
        try:
            s.recv(64)
            n += 1
        except socket.timeout:
            pass
    print(n)
