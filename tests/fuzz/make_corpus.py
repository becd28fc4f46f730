#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz targets into tests/fuzz/corpus/<target>/.

A few well-formed seeds per target (so the fuzzer starts deep) and every
known attack case, each file named after what it is. LCM seeds are encoded
with Python modules lcm-gen writes from msgs/*.lcm into a temporary folder,
so they carry the current fingerprints: run this again after a change to
msgs/ (python3 tests/fuzz/make_corpus.py) and commit the result.
"""
import gzip
import hashlib
import hmac
import importlib
import pathlib
import struct
import subprocess
import sys
import tempfile

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent
CORPUS = HERE / "corpus"


def write(target, name, data):
    folder = CORPUS / target
    folder.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    (folder / name).write_bytes(data)


def gz(data):
    if isinstance(data, str):
        data = data.encode()
    return gzip.compress(data, compresslevel=9, mtime=0)


CUBE_OBJ = """# unit cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 2 3 4
f 5 8 7 6
f 1 5 6 2
f 2 6 7 3
f 3 7 8 4
f 5 1 4 8
"""

PLY_ASCII = """ply
format ascii 1.0
comment one quad, one triangle
element vertex 4
property float x
property float y
property float z
element face 2
property list uchar int vertex_indices
end_header
0 0 0
1 0 0
1 1 0
0 1 0
4 0 1 2 3
3 0 2 1
"""


def ply_binary():
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
              "property float x\nproperty float y\nproperty float z\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n")
    body = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<B3i", 3, 0, 1, 2)
    return header.encode() + body


STL_ASCII = """solid tri
facet normal 0 0 1
  outer loop
    vertex 0 0 0
    vertex 1 0 0
    vertex 0 1 0
  endloop
endfacet
endsolid tri
"""


def stl_binary(count, triangles):
    data = b"binary stl seed".ljust(80, b" ") + struct.pack("<I", count)
    for _ in range(triangles):
        data += struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    return data


def meshes():
    write("fuzz_mesh_obj", "cube.obj", CUBE_OBJ)
    write("fuzz_mesh_obj", "cube.obj.gz", gz(CUBE_OBJ))
    write("fuzz_mesh_obj", "negative_indices.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n")
    write("fuzz_mesh_obj", "index_out_of_range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    write("fuzz_mesh_ply", "quad_ascii.ply", PLY_ASCII)
    write("fuzz_mesh_ply", "triangle_binary_le.ply", ply_binary())
    write("fuzz_mesh_ply", "quad_ascii.ply.gz", gz(PLY_ASCII))
    # Attack: an element with no properties and a count of 2e9 (a reader that
    # loops per element spins; one that reserves per count allocates).
    write("fuzz_mesh_ply", "attack_zero_property_element_count_2e9.ply",
          "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\n"
          "element face 0\nproperty list uchar int vertex_indices\nend_header\n")
    # Attack: a small gzip bomb, 16 MiB of zeros in 16 KiB (ratio ~1000).
    write("fuzz_mesh_ply", "attack_gzip_bomb_16MiB.ply.gz",
          gz(PLY_ASCII.encode() + bytes(16 << 20)))
    write("fuzz_mesh_stl", "triangle_ascii.stl", STL_ASCII)
    write("fuzz_mesh_stl", "triangle_binary.stl", stl_binary(1, 1))
    write("fuzz_mesh_stl", "triangle_binary.stl.gz", gz(stl_binary(1, 1)))
    # Attack: a binary STL announcing 2^32-1 triangles and holding one.
    write("fuzz_mesh_stl", "attack_binary_count_4294967295.stl", stl_binary(0xFFFFFFFF, 1))


SKELETON = """{"name": "example", "links": [
  {"name": "pelvis", "parent": null, "a": [0, 0, 0], "b": [0, 0.20, 0], "radius": 0.12},
  {"name": "spine", "parent": "pelvis", "a": [0, 0, 0], "b": [0, 0.30, 0], "radius": 0.10},
  {"name": "head", "parent": "spine", "a": [0, 0, 0], "b": [0, 0, 0], "radius": 0.09}]}
"""


def text_parsers():
    write("fuzz_skeleton", "spec_example.json", SKELETON)
    write("fuzz_skeleton", "loop.json",
          '{"name": "l", "links": [{"name": "a", "parent": "b", "a": [0,0,0], "b": [0,0,0], "radius": 1},'
          ' {"name": "b", "parent": "a", "a": [0,0,0], "b": [0,0,0], "radius": 1}]}')
    write("fuzz_skeleton", "deep_nesting.json", "[" * 1500 + "]" * 1500)
    # Pose lines: the first byte picks the link count (1 + byte % 64).
    write("fuzz_pose", "two_links.bin",
          b"\x01" + b'{"utime": 1000000, "links": [[0, 0, 0, 1, 0, 0, 0], [0.1, 0.2, 0.3, 0.7071, 0.7071, 0, 0]]}')
    write("fuzz_pose", "zero_quaternion.bin", b"\x00" + b'{"utime": 5, "links": [[0, 0, 0, 0, 0, 0, 0]]}')
    write("fuzz_pose", "huge_coordinate.bin", b"\x00" + b'{"utime": 5, "links": [[1e300, 0, 0, 1, 0, 0, 0]]}')
    write("fuzz_pose", "utime_overflow.bin", b"\x00" + b'{"utime": 18446744073709551616, "links": [[0, 0, 0, 1, 0, 0, 0]]}')
    write("fuzz_filter", "by_name_and_index.json",
          '{"ignore": [{"link": "foot_l", "object": 0}, {"link": "*", "object": "floor.obj"},'
          ' {"link": 2, "object": "*"}]}')
    write("fuzz_filter", "bad_index.json", '{"ignore": [{"link": -1, "object": 99}]}')
    # World files (SPEC 8), loaded beside the files world_fuzzer.cc writes.
    write("fuzz_world", "avatar_object_env.json",
          '{"avatars": [{"id": "alice", "skeleton": "bar.json", "poses": "alice.jsonl",'
          ' "ignore": [{"link": "bar", "entity": "cup"}, {"link": "bar", "object": "floor.obj"}]},'
          ' {"id": "bob", "skeleton": "bar.json", "poses": "alice.jsonl", "motion": "independent"}],'
          ' "objects": [{"id": "cup", "mesh": "cup.obj", "poses": "cup.jsonl"}], "env": ["floor.obj"]}')
    write("fuzz_world", "objects_only.json",
          '{"objects": [{"id": "cup", "mesh": "cup.obj", "poses": "cup.jsonl"}], "env": []}')
    write("fuzz_world", "duplicate_id.json",
          '{"avatars": [{"id": "cup", "skeleton": "bar.json", "poses": "alice.jsonl"}],'
          ' "objects": [{"id": "cup", "mesh": "cup.obj", "poses": "cup.jsonl"}]}')
    write("fuzz_world", "missing_mesh_and_escape.json",
          '{"objects": [{"id": "a\\u001b[31m", "mesh": "../../../../etc/none.obj", "poses": "cup.jsonl"}]}')
    # Found by fuzz_world: "" names the world's own folder, which opens but
    # cannot be read (libstdc++'s filebuf threw through the pose reader).
    write("fuzz_world", "attack_poses_name_a_folder.json",
          '{"avatars": [{"id": "alice", "skeleton": "bar.json", "poses": ""}],'
          ' "objects": [{"id": "cup", "mesh": "cup.obj", "poses": ""}]}')
    write("fuzz_world", "object_pose_lines.json",
          '{"utime": 1, "pose": [0, 0, 0, 0, 0, 0, 0]}\n{"utime": -5, "pose": [1e308, 0, 0, 1, 0, 0, 0]}\n'
          '{"utime": 9223372036854775808, "pose": [0, 0, 0, 1, 0, 0]}\n')
    write("fuzz_config", "deploy_sweptccd.yaml", (ROOT / "deploy" / "sweptccd.yaml").read_bytes())
    write("fuzz_config", "minimal.yaml",
          "environment: [room.ply]\nclients:\n  - {id: alice, skeleton: a.json, ignore: ['foot_l:0']}\n")
    write("fuzz_config", "anchors_and_tags.yaml",
          "base: &b {id: a, skeleton: s.json}\nenvironment: [!!str x.ply]\nclients: [*b, *b]\nworkers: 0x10\n")


def lcm_types(tmp):
    subprocess.run(["lcm-gen", "--python", "--ppath", str(tmp)] + sorted(map(str, (ROOT / "msgs").glob("*.lcm"))),
                   check=True)
    sys.path.insert(0, str(tmp))
    return importlib.import_module("sweptccd")


def record(m, link):
    r = m.contact_record_t()
    r.link, r.object, r.triangle, r.s = link, 0, 17, 0.25
    r.point_link, r.point_env, r.normal = [0.1, 0.2, 0.3], [0.1, 0.2, 0.25], [0, 0, 1]
    r.separation = -0.001
    return r


# The key the decoder fuzzer (decode_fuzzer.cc) verifies with: seeds signed
# with it start the fuzzer on the verifying path too.
FUZZ_KEY = bytes([0x5A]) * 32


def sign(data, key=FUZZ_KEY):
    """The bytes with their last 32 (the mac field) set to HMAC-SHA256 of the rest."""
    return data[:-32] + hmac.new(key, data[:-32], hashlib.sha256).digest()


def messages(m):
    fp = {name: getattr(m, name)._get_packed_fingerprint()
          for name in ("tracker_pose_t", "status_t", "contact_event_t", "rejection_t",
                       "join_request_t", "join_reply_t", "leave_t", "object_pose_t",
                       "shared_contact_t")}
    p = m.tracker_pose_t()
    p.utime, p.client_id, p.session, p.seq, p.num_links = 1000000, "alice", 1700000000000000, 7, 2
    p.position = [[0, 0, 1], [0, 0.2, 1]]
    p.orientation = [[1, 0, 0, 0], [0.7071, 0.7071, 0, 0]]
    p.mac = bytes(32)
    write("fuzz_decode_tracker_pose_t", "two_links.lcm", p.encode())
    write("fuzz_decode_tracker_pose_t", "two_links_signed.lcm", sign(p.encode()))
    # Attack: client_id length INT32_MIN, 36 bytes in all (lcm-gen's decoder
    # reads before the buffer: a segfault no try/catch stops).
    write("fuzz_decode_tracker_pose_t", "attack_client_id_length_int32_min.lcm",
          fp["tracker_pose_t"] + struct.pack(">qi", 1, -2**31) + bytes(16))
    # Attack: num_links = 2^26 in a short message (arrays sized from it: 1.5 GiB).
    write("fuzz_decode_tracker_pose_t", "attack_num_links_2pow26.lcm",
          fp["tracker_pose_t"] + struct.pack(">qi", 1, 2) + b"a\x00" +
          struct.pack(">qqi", 1, 1, 2**26) + bytes(48))
    # Attack the fuzzer found (then an out-of-memory): num_links 1080033280
    # (0x40600000, the high word of a double) in a 66-byte message.
    write("fuzz_decode_tracker_pose_t", "attack_num_links_1080033280_found_oom.lcm",
          fp["tracker_pose_t"] + struct.pack(">qi", 1000000, 6) + b"alice\x00" +
          struct.pack(">qqi", 1, 7, 0x40600000) + struct.pack(">dd", 0.7051, 0.7051) + bytes(4))
    s = m.status_t()
    s.utime, s.backend, s.renderer, s.security, s.num_clients = 5, "gpu", "llvmpipe", "signed", 1
    s.client_id, s.poses_received, s.pairs_answered, s.pairs_skipped = ["alice"], [10], [9], [0]
    s.rejected, s.seq_gaps, s.latency_median_us, s.latency_p99_us = [1], [0], [800.0], [2100.0]
    s.rate_limited = [0]
    s.queue_depth, s.dropped_total, s.rejected_unattributed, s.rejections_suppressed = 0, 0, 3, 0
    s.instance, s.live_joined, s.live_left, s.live_expired = 1700000000000000, 2, 1, 0
    s.mac = bytes(32)
    write("fuzz_decode_status_t", "one_client.lcm", s.encode())
    write("fuzz_decode_status_t", "one_client_signed.lcm", sign(s.encode()))
    # Attack: 2^24 clients announced in a short message (nine arrays sized from it).
    write("fuzz_decode_status_t", "attack_num_clients_2pow24.lcm",
          fp["status_t"] + struct.pack(">q", 5) + struct.pack(">i", 4) + b"cpu\x00" +
          struct.pack(">i", 1) + b"\x00" + struct.pack(">i", 9) + b"unsigned\x00" +
          struct.pack(">i", 2**24) + bytes(16))
    e = m.contact_event_t()
    e.utime, e.client_id, e.seq0, e.seq1, e.pair, e.utime0, e.utime1 = 9, "alice", 6, 7, 0, 100, 200
    e.result, e.error, e.initially_colliding, e.undecided = 1, "", False, False
    e.s_lo, e.s_hi, e.t_lo, e.t_hi = 0.25, 0.2501, 125.0, 125.01
    e.num_contacts, e.contacts, e.num_links, e.links = 0, [], 0, []
    e.receive_utime, e.compute_us, e.queue_us, e.skipped_pairs_total = 300, 40.0, 2.0, 0
    e.mac = bytes(32)
    # Where num_contacts starts: what follows it in a message with no
    # contacts and no links is num_contacts, num_links, 4 x 8 bytes, the mac.
    at_num_contacts = len(e.encode()) - (4 + 4 + 4 * 8 + 32)
    write("fuzz_decode_contact_event_t", "no_contacts.lcm", e.encode())
    e.num_contacts, e.contacts = 1, [record(m, 1)]
    b = m.link_bracket_t()
    b.link, b.s_lo, b.s_hi, b.t_lo, b.t_hi = 1, 0.25, 0.2501, 125.0, 125.01
    b.initially_colliding, b.undecided, b.has_witness, b.witness = False, False, True, record(m, 1)
    e.num_links, e.links = 1, [b]
    full = e.encode()
    assert struct.unpack(">i", full[at_num_contacts:at_num_contacts + 4])[0] == 1
    write("fuzz_decode_contact_event_t", "contact_per_link.lcm", full)
    write("fuzz_decode_contact_event_t", "contact_per_link_signed.lcm", sign(full))
    # Attack: 2^26 contacts announced, the message ends there (arrays of
    # 104-byte records sized from it: 7 GiB).
    write("fuzz_decode_contact_event_t", "attack_num_contacts_2pow26.lcm",
          full[:at_num_contacts] + struct.pack(">i", 2**26))
    # Attack: num_contacts 0, num_links INT32_MIN.
    write("fuzz_decode_contact_event_t", "attack_num_links_int32_min.lcm",
          full[:at_num_contacts] + struct.pack(">ii", 0, -2**31) + bytes(64))
    r = m.rejection_t()
    r.utime, r.client_id, r.seq, r.reason, r.message = 1, "mallory", -1, "decode_error", "bad"
    r.suppressed, r.mac = 4, bytes(32)
    write("fuzz_decode_rejection_t", "decode_error.lcm", r.encode())
    write("fuzz_decode_rejection_t", "decode_error_signed.lcm", sign(r.encode()))
    # Attack: reason length INT32_MIN.
    write("fuzz_decode_rejection_t", "attack_reason_length_int32_min.lcm",
          fp["rejection_t"] + struct.pack(">q", 1) + struct.pack(">i", 1) + b"\x00" +
          struct.pack(">q", -1) + struct.pack(">i", -2**31) + bytes(8))
    j = m.join_request_t()
    j.utime, j.client_id, j.nonce, j.public_key = 1700000000000000, "vr1", 42, bytes(range(32))
    j.motion, j.eps_s, j.delta_m = 0, 0.0, 0.0
    j.num_links, j.link_name, j.parent = 2, ["pelvis", "arm"], [-1, 0]
    j.a, j.b, j.radius = [[0, 0, 0], [0, 0, 0]], [[0, 0, 0.3], [0.3, 0, 0]], [0.1, 0.05]
    j.num_ignore, j.ignore, j.mac = 1, ["arm:0"], bytes(32)
    j.num_ignore_entities, j.ignore_entity_link = 1, ["arm"]
    j.ignore_entity, j.ignore_entity_other_link = ["bob"], ["*"]
    write("fuzz_decode_join_request_t", "two_links.lcm", j.encode())
    write("fuzz_decode_join_request_t", "two_links_signed.lcm", sign(j.encode()))
    # Attack: num_links 2^26 right after the fixed fields (five arrays sized from it).
    head = fp["join_request_t"] + struct.pack(">q", 1) + struct.pack(">i", 4) + b"vr1\x00" + \
        struct.pack(">q", 42) + bytes(32) + b"\x00" + struct.pack(">dd", 0, 0)
    write("fuzz_decode_join_request_t", "attack_num_links_2pow26.lcm",
          head + struct.pack(">i", 2**26) + bytes(64))
    # Attack: a link name of length INT32_MIN.
    write("fuzz_decode_join_request_t", "attack_link_name_length_int32_min.lcm",
          head + struct.pack(">ii", 1, -2**31) + bytes(96))
    rp = m.join_reply_t()
    rp.utime, rp.client_id, rp.nonce, rp.reason, rp.message = 1, "vr1", 42, 0, ""
    rp.session, rp.instance, rp.silence_timeout_ms = 1700000000000001, 1700000000000000, 5000
    rp.sealed_key_size, rp.sealed_key, rp.mac = 80, bytes(range(80)), bytes(32)
    write("fuzz_decode_join_reply_t", "accepted.lcm", rp.encode())
    write("fuzz_decode_join_reply_t", "accepted_signed.lcm", sign(rp.encode()))
    # Attack: sealed_key_size INT32_MIN.
    write("fuzz_decode_join_reply_t", "attack_sealed_key_size_int32_min.lcm",
          fp["join_reply_t"] + struct.pack(">q", 1) + struct.pack(">i", 4) + b"vr1\x00" +
          struct.pack(">q", 42) + b"\x00" + struct.pack(">i", 1) + b"\x00" +
          struct.pack(">qqq", 1, 1, 5000) + struct.pack(">i", -2**31) + bytes(32))
    lv = m.leave_t()
    lv.utime, lv.client_id, lv.session, lv.mac = 1, "vr1", 1700000000000001, bytes(32)
    write("fuzz_decode_leave_t", "leave.lcm", lv.encode())
    write("fuzz_decode_leave_t", "leave_signed.lcm", sign(lv.encode()))
    write("fuzz_decode_leave_t", "attack_client_id_length_int32_min.lcm",
          fp["leave_t"] + struct.pack(">qi", 1, -2**31) + bytes(40))
    op = m.object_pose_t()
    op.utime, op.object_id, op.session, op.seq = 1000000, "cup", 1700000000000000, 3
    op.position, op.orientation, op.mac = [0.5, 0, 0.8], [1, 0, 0, 0], bytes(32)
    write("fuzz_decode_object_pose_t", "cup.lcm", op.encode())
    write("fuzz_decode_object_pose_t", "cup_signed.lcm", sign(op.encode()))
    # Attack: object_id length INT32_MIN (as the 36-byte tracker_pose_t datagram).
    write("fuzz_decode_object_pose_t", "attack_object_id_length_int32_min.lcm",
          fp["object_pose_t"] + struct.pack(">qi", 1, -2**31) + bytes(16))
    ec = m.entity_contact_t()
    ec.link, ec.other_link, ec.triangle, ec.s = 3, -1, 12, 0.51
    ec.point_link, ec.point_other, ec.normal, ec.separation = [0, 0, 1], [0, 0, 0.9], [0, 0, 1], -1e-4
    cup = m.shared_entry_t()
    cup.entity, cup.entity_kind, cup.t_from, cup.t_to = "cup", 1, 1000000, 1011111
    cup.result, cup.error, cup.initially_colliding, cup.undecided = 1, "", False, False
    cup.s_lo, cup.s_hi, cup.t_lo, cup.t_hi = 0.5, 0.51, 1005555.0, 1005666.0
    cup.num_contacts, cup.contacts = 1, [ec]
    lb = m.entity_link_bracket_t()
    lb.link, lb.s_lo, lb.s_hi, lb.t_lo, lb.t_hi = 3, 0.5, 0.51, 1005555.0, 1005666.0
    lb.initially_colliding, lb.undecided, lb.has_witness, lb.witness = False, False, True, ec
    cup.num_links, cup.links = 1, [lb]
    cup.waited_us, cup.ended_by_timeout, cup.compute_us = 800, False, 12.5
    bob = m.shared_entry_t()
    bob.entity, bob.entity_kind, bob.t_from, bob.t_to = "bob", 0, 1000000, 1005000
    bob.result, bob.error, bob.initially_colliding, bob.undecided = 0, "", False, False
    bob.s_lo, bob.s_hi, bob.t_lo, bob.t_hi = 0, 0, 0, 0
    bob.num_contacts, bob.contacts, bob.num_links, bob.links = 0, [], 0, []
    bob.waited_us, bob.ended_by_timeout, bob.compute_us = 5000000, True, 3.5
    sc = m.shared_contact_t()
    sc.utime, sc.client_id, sc.seq0, sc.seq1, sc.pair = 1, "alice", 1, 2, 0
    sc.utime0, sc.utime1, sc.receive_utime = 1000000, 1011111, 5
    sc.num_entries, sc.entries = 2, [cup, bob]
    sc.mac = bytes(32)
    write("fuzz_decode_shared_contact_t", "contact.lcm", sc.encode())
    write("fuzz_decode_shared_contact_t", "contact_signed.lcm", sign(sc.encode()))
    # Attack: num_entries = 2^26 in a short message.
    sc.num_entries, sc.entries = 0, []
    raw = bytearray(sc.encode())
    at = 8 + 8 + (4 + 6) + 6 * 8
    raw[at:at + 4] = struct.pack(">i", 2**26)
    write("fuzz_decode_shared_contact_t", "attack_num_entries_2pow26.lcm", bytes(raw))
    # Attack: one entry whose num_contacts = 2^26.
    cup.num_contacts, cup.contacts, cup.num_links, cup.links = 0, [], 0, []
    sc.num_entries, sc.entries = 1, [cup]
    raw = bytearray(sc.encode())
    at = 8 + 8 + (4 + 6) + 6 * 8 + 4 + (4 + 4) + 17 + 1 + 5 + 2 + 32
    raw[at:at + 4] = struct.pack(">i", 2**26)
    write("fuzz_decode_shared_contact_t", "attack_num_contacts_2pow26.lcm", bytes(raw))


def main():
    # Every seed below is written again; files this script does not write
    # (reproducers a fuzzer found: crash_*, and the PLY ones named in
    # core/geometry/mesh_precheck.cc and tests/core/geometry/mesh_test.cc) are
    # kept. A seed renamed here leaves its old file: delete it by hand.
    meshes()
    text_parsers()
    with tempfile.TemporaryDirectory() as tmp:
        messages(lcm_types(pathlib.Path(tmp)))
    for folder in sorted(CORPUS.iterdir()):
        print(f"{folder.name}: {len(list(folder.iterdir()))} seeds")


if __name__ == "__main__":
    main()
