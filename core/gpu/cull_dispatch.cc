#include "core/gpu/cull_dispatch.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <string>

#include "core/gpu/gl_context.h"

namespace sweptccd::gpu::internal {

namespace {

// One invocation per capsule: a depth-first walk of each unfiltered object's
// BVH (box overlap, exact in float), then per triangle a certificate of
// separation along two axes. Writes 1 unless every triangle is certified
// farther than the radius. See docs/GPU.md for the rounding argument.
constexpr char kShaderHead[] = R"GLSL(
#version 430
layout(local_size_x = 64) in;
)GLSL";

// The search, shared by this dispatch's shader and the device descent's
// (core/gpu/descent_dispatch.cc): bindings 0-3 and the search functions.
constexpr char kSearchGlsl[] = R"GLSL(
layout(std430, binding = 0) readonly buffer Nodes { uint node_words[]; };  // 8 words per node
layout(std430, binding = 1) readonly buffer Tris { float tri[]; };         // 9 floats per slot
layout(std430, binding = 2) readonly buffer Objects { uvec4 objects[]; };  // node offset, slot offset, nodes
layout(std430, binding = 3) readonly buffer Masks { uint masks[]; };       // ignored objects per link, per filter

uniform uint u_num_objects;
uniform uint u_mask_words;

// Each dot product below is within 6u * sum |n_i x_i| of exact (u = 2^-24;
// GLSL 4.30 section 4.7.1 makes a + b and a * b correctly rounded but leaves
// the rounding mode open, so 2u per operation); kDotSlack is 16u. kGrow
// covers the roundings of the final comparison and of sqrt.
const float kDotSlack = 1.0 / 1048576.0;
const float kGrow = 1.0 + 1.0 / 65536.0;

// The answer written for a capsule proved clear; anything else (0 from a
// buffer that was never written, say) reads as "may touch".
const uint kCleared = 0xC1EA4EDu;

// True only when every point of segment a-b is farther than r from the
// triangle, certified along axis n_in: the projections of the two convex sets
// on it are apart by more than r |n| after the rounding bounds are taken off.
// The axis is first scaled by a power of two (exact) so that its largest
// component is in [0.5, 1): |n| then cannot underflow (a tiny cross product
// of a sliver triangle once made r |n| vanish and certified anything).
// An axis that is zero, tiny, huge or not finite is not used.
bool SeparatedAlong(vec3 n_in, vec3 a, vec3 b, vec3 v0, vec3 v1, vec3 v2, float r) {
  float m = max(max(abs(n_in.x), abs(n_in.y)), abs(n_in.z));
  if (!(m >= 1e-30 && m <= 1e30)) return false;
  int e;
  frexp(m, e);
  precise vec3 n = ldexp(n_in, ivec3(-e));
  precise float sa = dot(n, a);
  precise float sb = dot(n, b);
  precise float t0 = dot(n, v0);
  precise float t1 = dot(n, v1);
  precise float t2 = dot(n, v2);
  vec3 an = abs(n);
  float mag = max(max(dot(an, abs(a)), dot(an, abs(b))),
                  max(max(dot(an, abs(v0)), dot(an, abs(v1))), dot(an, abs(v2))));
  precise float gap = max(min(sa, sb) - max(max(t0, t1), t2),
                          min(min(t0, t1), t2) - max(sa, sb));
  precise float need = (r * sqrt(dot(n, n)) + 2.0 * kDotSlack * mag) * kGrow + 1e-30;
  return gap > need;
}

vec3 ClosestOnTriangle(vec3 p, vec3 a, vec3 b, vec3 c) {
  vec3 ab = b - a, ac = c - a, ap = p - a;
  float d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  vec3 bp = p - b;
  float d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + (d1 / (d1 - d3)) * ab;
  vec3 cp = p - c;
  float d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + (d2 / (d2 - d6)) * ac;
  float va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  float denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

// Approximate closest points of segments p1-q1 and p2-q2 (any pair of points
// on them will do: the certificate does not trust them).
void ClosestSegmentSegment(vec3 p1, vec3 q1, vec3 p2, vec3 q2, out vec3 c1, out vec3 c2) {
  vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  float a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
  float s = 0.0, t = 0.0;
  if (a <= 1e-30 && e <= 1e-30) {
  } else if (a <= 1e-30) {
    t = clamp(f / e, 0.0, 1.0);
  } else {
    float c = dot(d1, r);
    if (e <= 1e-30) {
      s = clamp(-c / a, 0.0, 1.0);
    } else {
      float b = dot(d1, d2);
      float denom = a * e - b * b;
      s = denom > 0.0 ? clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = clamp(-c / a, 0.0, 1.0);
      } else if (t > 1.0) {
        t = 1.0;
        s = clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  c1 = p1 + d1 * s;
  c2 = p2 + d2 * t;
}

bool TriangleSeparated(vec3 a, vec3 b, float r, vec3 v0, vec3 v1, vec3 v2) {
  // Axis 1: the triangle's normal.
  if (SeparatedAlong(cross(v1 - v0, v2 - v0), a, b, v0, v1, v2, r)) return true;
  // Axis 2: between approximate closest points.
  vec3 best_s = a, best_t = ClosestOnTriangle(a, v0, v1, v2);
  float best = dot(best_s - best_t, best_s - best_t);
  vec3 q = ClosestOnTriangle(b, v0, v1, v2);
  if (dot(b - q, b - q) < best) { best_s = b; best_t = q; best = dot(b - q, b - q); }
  vec3 cs, ct;
  ClosestSegmentSegment(a, b, v0, v1, cs, ct);
  if (dot(cs - ct, cs - ct) < best) { best_s = cs; best_t = ct; best = dot(cs - ct, cs - ct); }
  ClosestSegmentSegment(a, b, v1, v2, cs, ct);
  if (dot(cs - ct, cs - ct) < best) { best_s = cs; best_t = ct; best = dot(cs - ct, cs - ct); }
  ClosestSegmentSegment(a, b, v2, v0, cs, ct);
  if (dot(cs - ct, cs - ct) < best) { best_s = cs; best_t = ct; }
  return SeparatedAlong(best_s - best_t, a, b, v0, v1, v2, r);
}

bool BoxesOverlap(vec3 lo0, vec3 hi0, vec3 lo1, vec3 hi1) {
  return all(lessThanEqual(lo0, hi1)) && all(lessThanEqual(lo1, hi0));
}

// The whole search is one loop, each iteration one step: the next object,
// one BVH node, or one triangle of the leaf in hand. Past u_max_steps steps
// (set by the host: kCullMaxSteps for the culler, DescentOptions::max_steps
// for the device descent, never above kMaxSearchSteps, cull_dispatch.h) the
// invocation gives up and answers "may touch" (the CPU decides). A
// driver may end long loops on its own: Mesa's llvmpipe ends a shader's
// loops, silently, once their iterations reach 65535
// (LP_MAX_TGSI_LOOP_ITERATIONS, one count for all loops, kept per group of
// invocations run together in SIMD lanes), which left a traversal
// unfinished and its capsule "cleared" (misses on the Stanford bunny,
// GpuCullerTest.LongTraversalsAreNeverCleared). With one loop, a group runs
// it as often as its busiest invocation, at most u_max_steps + 2 times, far
// below that limit; and only a search that reached its end writes kCleared,
// so an unfinished one can only answer "may touch" (a cap left unset reads
// 0: nothing is cleared).
// The cap also bounds one capsule's time on a real GPU.
uniform uint u_max_steps;

// kCleared when every unfiltered triangle is certified farther than r from
// segment a-b (lo, hi: a box holding the capsule; link and mask_base: whose
// collision filter), anything else when not.
uint Search(vec3 a, vec3 b, float r, vec3 lo, vec3 hi, uint link, uint mask_base) {
  uint hit = 0u;
  bool searched = false;  // Every object searched to its end.
  uint stack[128];
  int top = 0;                    // Nodes left of the current object.
  uint next_object = 0u;          // The object after the current one.
  uvec4 obj = uvec4(0u);          // The current object: node offset, slot offset, nodes.
  uint leaf = 0u, leaf_end = 0u;  // Slots left of the leaf in hand, [leaf, leaf_end).
  for (uint steps = 0u; hit == 0u; ++steps) {
    if (steps >= u_max_steps) { hit = 1u; break; }
    if (leaf < leaf_end) {  // A triangle of the leaf in hand.
      uint t = 9u * (obj.y + leaf);
      ++leaf;
      vec3 v0 = vec3(tri[t], tri[t + 1u], tri[t + 2u]);
      vec3 v1 = vec3(tri[t + 3u], tri[t + 4u], tri[t + 5u]);
      vec3 v2 = vec3(tri[t + 6u], tri[t + 7u], tri[t + 8u]);
      if (!BoxesOverlap(lo, hi, min(min(v0, v1), v2), max(max(v0, v1), v2))) continue;
      if (!TriangleSeparated(a, b, r, v0, v1, v2)) hit = 1u;
      continue;
    }
    if (top > 0) {  // A node of the current object.
      uint w = 8u * (obj.x + stack[--top]);
      vec3 nlo = vec3(uintBitsToFloat(node_words[w]), uintBitsToFloat(node_words[w + 1u]),
                      uintBitsToFloat(node_words[w + 2u]));
      vec3 nhi = vec3(uintBitsToFloat(node_words[w + 3u]), uintBitsToFloat(node_words[w + 4u]),
                      uintBitsToFloat(node_words[w + 5u]));
      if (!BoxesOverlap(lo, hi, nlo, nhi)) continue;
      uint first = node_words[w + 6u], count = node_words[w + 7u];
      if (count == 0u) {
        if (top > 126) { hit = 1u; break; }  // Cannot happen (depth < 128); stay conservative.
        stack[top++] = first + 1u;
        stack[top++] = first;
      } else {
        leaf = first;
        leaf_end = first + count;
      }
      continue;
    }
    if (next_object >= u_num_objects) {  // Every object searched: cleared.
      searched = true;
      break;
    }
    uint o = next_object++;
    if ((masks[mask_base + link * u_mask_words + (o >> 5)] & (1u << (o & 31u))) != 0u) continue;
    obj = objects[o];
    if (obj.z == 0u) continue;  // No triangles.
    stack[top++] = 0u;
  }
  // Only a search that ran to its end clears: a loop ended any other way
  // (the cap, a driver's limit) answers "may touch".
  return hit == 0u && searched ? kCleared : 1u;
}
)GLSL";

// One invocation per capsule sent by the host.
constexpr char kCullMain[] = R"GLSL(
struct Capsule { vec4 a_r; vec4 b; vec4 lo; vec4 hi; uvec4 meta; };
layout(std430, binding = 4) readonly buffer Capsules { Capsule caps[]; };
layout(std430, binding = 5) writeonly buffer Hits { uint hits[]; };
uniform uint u_num_capsules;

void main() {
  uint id = gl_GlobalInvocationID.x;
  if (id >= u_num_capsules) return;
  Capsule cap = caps[id];
  // meta.y: this capsule's filter's table (one buffer holds every filter's).
  hits[id] = Search(cap.a_r.xyz, cap.b.xyz, cap.a_r.w, cap.lo.xyz, cap.hi.xyz, cap.meta.x,
                    cap.meta.y);
}
)GLSL";

bool HasGlExtension(const char* name) {
  GLint n = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &n);
  for (GLint i = 0; i < n; ++i) {
    const GLubyte* e = glGetStringi(GL_EXTENSIONS, static_cast<GLuint>(i));
    if (e != nullptr && std::strcmp(reinterpret_cast<const char*>(e), name) == 0) return true;
  }
  return false;
}

// Whether glBufferStorage and persistent mappings exist here.
bool HasBufferStorage() {
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  return major * 10 + minor >= 44 || HasGlExtension("GL_ARB_buffer_storage");
}

constexpr GLbitfield kPersistentWrite =
    GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
constexpr GLbitfield kPersistentReadWrite =
    GL_MAP_READ_BIT | GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;

// Waits for `sync` (flushing first); a wait that fails, or a fence not
// signalled after 10 minutes (a lost or hung device), throws.
void WaitFor(GLsync sync) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::minutes(10);
  GLbitfield flags = GL_SYNC_FLUSH_COMMANDS_BIT;
  for (;;) {
    const GLenum r = glClientWaitSync(sync, flags, 100000000);  // 0.1 s, in ns.
    if (r == GL_ALREADY_SIGNALED || r == GL_CONDITION_SATISFIED) break;
    if (r == GL_WAIT_FAILED || std::chrono::steady_clock::now() > give_up) {
      glDeleteSync(sync);
      throw GpuError(r == GL_WAIT_FAILED ? "waiting for the swept-volume test failed"
                                         : "the swept-volume test did not finish in 10 minutes");
    }
    flags = 0;  // Flushed once is enough.
  }
  glDeleteSync(sync);
}

}  // namespace

std::string SearchGlsl() { return kSearchGlsl; }
std::string ShaderHead() { return kShaderHead; }

CullDispatch::CullDispatch(const EnvironmentBuffers& env, Transfer transfer)
    : env_(env), transfer_(transfer) {
  mask_words_ = std::max<uint32_t>(1, (env.num_objects + 31) / 32);
  if (transfer_ != Transfer::kReadBack) {
    if (HasBufferStorage()) {
      transfer_ = Transfer::kPersistent;
    } else {
      spdlog::info(
          "GPU: no glBufferStorage (OpenGL 4.4 / GL_ARB_buffer_storage): capsules "
          "and answers cross by read-back");
      transfer_ = Transfer::kReadBack;
    }
  }
  program_ = CompileProgram((std::string(kShaderHead) + kSearchGlsl + kCullMain).c_str());
  loc_num_capsules_ = glGetUniformLocation(program_, "u_num_capsules");
  loc_num_objects_ = glGetUniformLocation(program_, "u_num_objects");
  loc_mask_words_ = glGetUniformLocation(program_, "u_mask_words");
  loc_max_steps_ = glGetUniformLocation(program_, "u_max_steps");
  glGenBuffers(1, &masks_buffer_);
  CheckGl("creating the swept-volume test");
}

CullDispatch::~CullDispatch() {
  FreeIo();
  glDeleteBuffers(1, &masks_buffer_);
  glDeleteProgram(program_);
}

void CullDispatch::FreeIo() {
  if (mapped_caps_ != nullptr) {
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, caps_buffer_);
    glUnmapBuffer(GL_SHADER_STORAGE_BUFFER);
  }
  if (mapped_hits_ != nullptr) {
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, hits_buffer_);
    glUnmapBuffer(GL_SHADER_STORAGE_BUFFER);
  }
  mapped_caps_ = nullptr;
  mapped_hits_ = nullptr;
  const GLuint names[] = {caps_buffer_, hits_buffer_};
  glDeleteBuffers(2, names);
  caps_buffer_ = hits_buffer_ = 0;
  capacity_ = 0;
}

void CullDispatch::Reserve(size_t n) {
  if (n <= capacity_) return;
  const size_t capacity = std::max({n, 2 * capacity_, size_t{64}});
  FreeIo();
  glGenBuffers(1, &caps_buffer_);
  glGenBuffers(1, &hits_buffer_);
  const auto caps_bytes = static_cast<GLsizeiptr>(capacity * sizeof(GpuCapsule));
  const auto hits_bytes = static_cast<GLsizeiptr>(capacity * sizeof(uint32_t));
  if (transfer_ == Transfer::kPersistent) {
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, caps_buffer_);
    glBufferStorage(GL_SHADER_STORAGE_BUFFER, caps_bytes, nullptr, kPersistentWrite);
    mapped_caps_ = static_cast<GpuCapsule*>(
        glMapBufferRange(GL_SHADER_STORAGE_BUFFER, 0, caps_bytes, kPersistentWrite));
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, hits_buffer_);
    glBufferStorage(GL_SHADER_STORAGE_BUFFER, hits_bytes, nullptr, kPersistentReadWrite);
    mapped_hits_ = static_cast<uint32_t*>(
        glMapBufferRange(GL_SHADER_STORAGE_BUFFER, 0, hits_bytes, kPersistentReadWrite));
    if (glGetError() != GL_NO_ERROR || mapped_caps_ == nullptr || mapped_hits_ == nullptr) {
      // Offered but refused: read-back from now on.
      spdlog::warn("GPU: persistent mapped buffers refused by the driver; read-back instead");
      FreeIo();
      transfer_ = Transfer::kReadBack;
      Reserve(n);
      return;
    }
  } else {
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, caps_buffer_);
    glBufferData(GL_SHADER_STORAGE_BUFFER, caps_bytes, nullptr, GL_DYNAMIC_DRAW);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, hits_buffer_);
    glBufferData(GL_SHADER_STORAGE_BUFFER, hits_bytes, nullptr, GL_DYNAMIC_READ);
  }
  CheckGl("allocating the capsule buffers");
  capacity_ = capacity;
}

uint32_t CullDispatch::AddMasks(const std::vector<uint32_t>& masks) {
  const size_t size = std::max<size_t>(1, masks.size());
  uint32_t offset = static_cast<uint32_t>(masks_.size());
  bool reused = false;
  for (auto it = free_spans_.begin(); it != free_spans_.end(); ++it) {
    if (it->second < size) continue;
    offset = it->first;
    if (it->second > size) {
      *it = {static_cast<uint32_t>(it->first + size), it->second - size};
    } else {
      free_spans_.erase(it);
    }
    reused = true;
    break;
  }
  if (!reused) {
    if (masks_.size() + size > UINT32_MAX / 2) throw GpuError("too many collision filters");
    masks_.resize(masks_.size() + size, 0u);
  }
  std::copy(masks.begin(), masks.end(), masks_.begin() + offset);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, masks_buffer_);
  if (masks_.size() > masks_capacity_) {
    masks_capacity_ = std::max(masks_.size(), 2 * masks_capacity_);
    glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(masks_capacity_ * 4), nullptr,
                 GL_STATIC_DRAW);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(masks_.size() * 4),
                    masks_.data());
  } else {
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, static_cast<GLintptr>(offset) * 4,
                    static_cast<GLsizeiptr>(size * 4), masks_.data() + offset);
  }
  CheckGl("uploading a collision filter");
  return offset;
}

void CullDispatch::RemoveMasks(uint32_t offset, size_t size) {
  free_spans_.emplace_back(offset, std::max<size_t>(1, size));
}

void CullDispatch::Run(const GpuCapsule* capsules, size_t n, uint32_t* answers) {
  if (n == 0) return;
  Reserve(n);
  if (transfer_ == Transfer::kPersistent) {
    // Coherent: these writes are seen by the commands issued after them.
    std::memcpy(mapped_caps_, capsules, n * sizeof(GpuCapsule));
    std::memset(mapped_hits_, 0, n * sizeof(uint32_t));  // Unwritten reads "may touch".
  } else {
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, caps_buffer_);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(n * sizeof(GpuCapsule)),
                    capsules);
  }
  glUseProgram(program_);
  glUniform1ui(loc_num_capsules_, static_cast<GLuint>(n));
  glUniform1ui(loc_num_objects_, env_.num_objects);
  glUniform1ui(loc_mask_words_, mask_words_);
  glUniform1ui(loc_max_steps_, kCullMaxSteps);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, env_.nodes);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, env_.tris);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, env_.objects);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, masks_buffer_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, caps_buffer_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, hits_buffer_);
  glDispatchCompute(static_cast<GLuint>((n + 63) / 64), 1, 1);
  if (transfer_ == Transfer::kPersistent) {
    // The shader's writes reach the mapping once the fence after this
    // barrier is signalled (OpenGL 4.6 section 7.13.3).
    glMemoryBarrier(GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
    GLsync sync = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
    if (sync == nullptr) throw GpuError("glFenceSync failed");
    WaitFor(sync);
    std::memcpy(answers, mapped_hits_, n * sizeof(uint32_t));
  } else {
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, hits_buffer_);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(n * 4), answers);
  }
  CheckGl("the swept-volume test");
}

}  // namespace sweptccd::gpu::internal

namespace sweptccd::gpu {

const char* TransferName(Transfer transfer) {
  switch (transfer) {
    case Transfer::kBest:
      return "best";
    case Transfer::kReadBack:
      return "read-back";
    case Transfer::kPersistent:
      return "persistent mapped buffers and a fence";
  }
  return "?";
}

}  // namespace sweptccd::gpu
