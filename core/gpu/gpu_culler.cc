#include "core/gpu/gpu_culler.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>

#include "core/gpu/gl_api.h"

namespace sweptccd::gpu {

namespace {

// One invocation per capsule: a depth-first walk of each unfiltered object's
// BVH (box overlap, exact in float), then per triangle a certificate of
// separation along two axes. Writes 1 unless every triangle is certified
// farther than the radius. See docs/GPU.md for the rounding argument.
constexpr char kCullShader[] = R"GLSL(
#version 430
layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Nodes { uint node_words[]; };  // 8 words per node
layout(std430, binding = 1) readonly buffer Tris { float tri[]; };         // 9 floats per slot
layout(std430, binding = 2) readonly buffer Objects { uvec4 objects[]; };  // node offset, slot offset, nodes
layout(std430, binding = 3) readonly buffer Masks { uint masks[]; };       // ignored objects per link
struct Capsule { vec4 a_r; vec4 b; vec4 lo; vec4 hi; uvec4 meta; };
layout(std430, binding = 4) readonly buffer Capsules { Capsule caps[]; };
layout(std430, binding = 5) writeonly buffer Hits { uint hits[]; };

uniform uint u_num_capsules;
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
// one BVH node, or one triangle of the leaf in hand. Past kMaxSteps steps
// the invocation gives up and answers "may touch" (the CPU decides). A
// driver may end long loops on its own: Mesa's llvmpipe ends a shader's
// loops, silently, once their iterations reach 65535
// (LP_MAX_TGSI_LOOP_ITERATIONS, one count for all loops, kept per group of
// invocations run together in SIMD lanes), which left a traversal
// unfinished and its capsule "cleared" (misses on the Stanford bunny,
// GpuCullerTest.LongTraversalsAreNeverCleared). With one loop, a group runs
// it as often as its busiest invocation, at most kMaxSteps + 2 times, far
// below that limit; and only a search that reached its end writes kCleared,
// so an unfinished one can only answer "may touch".
// The cap also bounds one capsule's time on a real GPU.
const uint kMaxSteps = 16384u;

void main() {
  uint id = gl_GlobalInvocationID.x;
  if (id >= u_num_capsules) return;
  Capsule cap = caps[id];
  vec3 a = cap.a_r.xyz, b = cap.b.xyz;
  float r = cap.a_r.w;
  vec3 lo = cap.lo.xyz, hi = cap.hi.xyz;
  uint link = cap.meta.x;
  uint hit = 0u;
  bool searched = false;  // Every object searched to its end.
  uint stack[128];
  int top = 0;                    // Nodes left of the current object.
  uint next_object = 0u;          // The object after the current one.
  uvec4 obj = uvec4(0u);          // The current object: node offset, slot offset, nodes.
  uint leaf = 0u, leaf_end = 0u;  // Slots left of the leaf in hand, [leaf, leaf_end).
  for (uint steps = 0u; hit == 0u; ++steps) {
    if (steps >= kMaxSteps) { hit = 1u; break; }
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
    if ((masks[link * u_mask_words + (o >> 5)] & (1u << (o & 31u))) != 0u) continue;
    obj = objects[o];
    if (obj.z == 0u) continue;  // No triangles.
    stack[top++] = 0u;
  }
  // Only a search that ran to its end clears: a loop ended any other way
  // (the cap, a driver's limit) answers "may touch".
  hits[id] = hit == 0u && searched ? kCleared : 1u;
}
)GLSL";

// The shader's kCleared.
constexpr uint32_t kClearedAnswer = 0xC1EA4EDu;

struct GpuCapsule {
  float a_r[4];
  float b[4];
  float lo[4];
  float hi[4];
  uint32_t meta[4];
};
static_assert(sizeof(GpuCapsule) == 80, "std430 layout of Capsule");

float RoundDown(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

float RoundUp(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// The float capsule that contains the double one: endpoints rounded to
// nearest, the radius grown by their displacement and rounded up, the box
// rounded outwards.
GpuCapsule ToGpu(const LinkCapsule& c) {
  GpuCapsule g{};
  double moved = 0;
  for (int k = 0; k < 3; ++k) {
    g.a_r[k] = static_cast<float>(c.a[k]);
    g.b[k] = static_cast<float>(c.b[k]);
  }
  const Eigen::Vector3d af(g.a_r[0], g.a_r[1], g.a_r[2]), bf(g.b[0], g.b[1], g.b[2]);
  moved = std::max((af - c.a).norm(), (bf - c.b).norm());
  const double r = (c.radius + moved) * (1 + 1e-12);
  g.a_r[3] = RoundUp(r);
  for (int k = 0; k < 3; ++k) {
    g.lo[k] = RoundDown(std::min(c.a[k], c.b[k]) - r);
    g.hi[k] = RoundUp(std::max(c.a[k], c.b[k]) + r);
  }
  g.meta[0] = static_cast<uint32_t>(c.link);
  return g;
}

}  // namespace

struct GpuEnvironment::Buffers {
  GLuint nodes = 0, tris = 0, objects = 0;
};

GpuEnvironment::GpuEnvironment(std::shared_ptr<GlContext> context, const Environment& environment)
    : context_(std::move(context)), buffers_(std::make_unique<Buffers>()) {
  num_objects_ = environment.num_objects();
  std::vector<uint32_t> table;
  size_t num_nodes = 0, num_slots = 0;
  for (int o = 0; o < num_objects_; ++o) {
    const TriangleBvh& bvh = environment.object(o).bvh;
    table.insert(table.end(), {static_cast<uint32_t>(num_nodes), static_cast<uint32_t>(num_slots),
                               static_cast<uint32_t>(bvh.nodes().size()), 0u});
    num_nodes += bvh.nodes().size();
    num_slots += bvh.num_triangles();
  }
  if (num_nodes > std::numeric_limits<uint32_t>::max() / 8 ||
      num_slots > std::numeric_limits<uint32_t>::max() / 9) {
    throw GpuError("the environment is too large for the GPU backend's 32-bit indices");
  }
  std::vector<TriangleBvh::Node> nodes;
  std::vector<float> tris;
  nodes.reserve(num_nodes);
  tris.reserve(9 * num_slots);
  for (int o = 0; o < num_objects_; ++o) {
    const TriangleBvh& bvh = environment.object(o).bvh;
    nodes.insert(nodes.end(), bvh.nodes().begin(), bvh.nodes().end());
    Eigen::Vector3d p[3];
    for (uint32_t s = 0; s < bvh.num_triangles(); ++s) {
      bvh.Triangle(s, &p[0], &p[1], &p[2]);
      for (const Eigen::Vector3d& v : p) {
        for (int k = 0; k < 3; ++k) tris.push_back(static_cast<float>(v[k]));  // Exact: stored as float.
      }
    }
  }
  if (table.empty()) table.assign(4, 0u);
  if (nodes.empty()) nodes.resize(1);
  if (tris.empty()) tris.resize(9);
  static_assert(sizeof(TriangleBvh::Node) == 32, "8 words per node in the shader");
  uploaded_bytes_ = nodes.size() * sizeof(nodes[0]) + tris.size() * sizeof(float) +
                    table.size() * sizeof(uint32_t);
  Buffers& b = *buffers_;
  context_->Run([&] {
    // Reads past this limit are undefined: refuse rather than miss triangles.
    GLint64 max_block = 0;
    glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
    const size_t largest = std::max(nodes.size() * sizeof(nodes[0]), tris.size() * sizeof(float));
    if (max_block > 0 && largest > static_cast<size_t>(max_block)) {
      throw GpuError("the environment needs a " + std::to_string(largest >> 20) +
                     " MiB storage buffer; this GPU allows " + std::to_string(max_block >> 20) +
                     " MiB (GL_MAX_SHADER_STORAGE_BLOCK_SIZE)");
    }
    auto upload = [](GLuint* name, const void* data, size_t bytes) {
      glGenBuffers(1, name);
      glBindBuffer(GL_SHADER_STORAGE_BUFFER, *name);
      glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(bytes), data, GL_STATIC_DRAW);
    };
    upload(&b.nodes, nodes.data(), nodes.size() * sizeof(nodes[0]));
    upload(&b.tris, tris.data(), tris.size() * sizeof(float));
    upload(&b.objects, table.data(), table.size() * sizeof(uint32_t));
    glFinish();
    internal::CheckGl("uploading the environment");
  });
  spdlog::info("GPU: environment resident, {} objects, {:.1f} MiB", num_objects_,
               uploaded_bytes_ / 1048576.0);
}

GpuEnvironment::~GpuEnvironment() {
  try {
    const Buffers b = *buffers_;
    context_->Run([b] {
      const GLuint names[] = {b.nodes, b.tris, b.objects};
      glDeleteBuffers(3, names);
    });
  } catch (const GpuError&) {
    // A lost context took its buffers with it.
  }
}

struct GpuCuller::State {
  int num_links = 0;
  int mask_words = 1;
  std::vector<uint32_t> masks;
  // GL objects, touched only on the owner thread.
  GLuint program = 0, masks_buffer = 0, caps_buffer = 0, hits_buffer = 0;
  size_t caps_capacity = 0;
  GLint loc_num_capsules = -1, loc_num_objects = -1, loc_mask_words = -1;
  std::vector<uint32_t> hits;

  std::mutex failure_mutex;
  std::atomic<bool> failed{false};
  std::atomic<int64_t> round_trips{0}, capsules{0};
};

GpuCuller::GpuCuller(std::shared_ptr<const GpuEnvironment> environment,
                     const CollisionFilter& filter, int num_links)
    : env_(std::move(environment)), state_(std::make_unique<State>()) {
  State& s = *state_;
  s.num_links = num_links;
  s.mask_words = std::max(1, (env_->num_objects() + 31) / 32);
  s.masks.assign(static_cast<size_t>(std::max(1, num_links)) * s.mask_words, 0u);
  for (int l = 0; l < num_links; ++l) {
    for (int o = 0; o < env_->num_objects(); ++o) {
      if (filter.Ignores(LinkIndex(l), ObjectIndex(o))) s.masks[l * s.mask_words + o / 32] |= 1u << (o % 32);
    }
  }
  env_->context().Run([&s] {
    s.program = internal::CompileProgram(kCullShader);
    s.loc_num_capsules = glGetUniformLocation(s.program, "u_num_capsules");
    s.loc_num_objects = glGetUniformLocation(s.program, "u_num_objects");
    s.loc_mask_words = glGetUniformLocation(s.program, "u_mask_words");
    glGenBuffers(1, &s.masks_buffer);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, s.masks_buffer);
    glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(s.masks.size() * 4),
                 s.masks.data(), GL_STATIC_DRAW);
    glGenBuffers(1, &s.caps_buffer);
    glGenBuffers(1, &s.hits_buffer);
    internal::CheckGl("creating the swept-volume test");
  });
}

GpuCuller::~GpuCuller() {
  State* s = state_.get();
  try {
    env_->context().Run([s] {
      const GLuint names[] = {s->masks_buffer, s->caps_buffer, s->hits_buffer};
      glDeleteBuffers(3, names);
      glDeleteProgram(s->program);
    });
  } catch (const GpuError&) {
  }
}

int64_t GpuCuller::round_trips() const { return state_->round_trips; }
int64_t GpuCuller::capsules_tested() const { return state_->capsules; }

bool GpuCuller::Cull(const std::vector<LinkCapsule>& capsules,
                     std::vector<uint8_t>* may_touch) const {
  State& s = *state_;
  may_touch->assign(capsules.size(), 1);
  if (capsules.empty()) return true;
  if (s.failed) return false;
  std::vector<GpuCapsule> upload(capsules.size());
  // Capsules a float cannot hold (not finite, beyond 1e30) are never cleared.
  std::vector<uint8_t> unusable(capsules.size(), 0);
  for (size_t i = 0; i < capsules.size(); ++i) {
    const LinkCapsule& c = capsules[i];
    if (c.link < 0 || c.link >= s.num_links) return false;
    const double extent = std::max({c.a.cwiseAbs().maxCoeff(), c.b.cwiseAbs().maxCoeff(), c.radius});
    if (!(extent <= 1e30) || !(c.radius >= 0)) {
      unusable[i] = 1;
      upload[i] = GpuCapsule{};
      upload[i].meta[0] = static_cast<uint32_t>(c.link);
      continue;
    }
    upload[i] = ToGpu(c);
  }
  const GpuEnvironment::Buffers& env = env_->buffers();
  const GLuint num_objects = static_cast<GLuint>(env_->num_objects());
  try {
    env_->context().Run([&] {
      const size_t n = upload.size();
      glBindBuffer(GL_SHADER_STORAGE_BUFFER, s.caps_buffer);
      if (n > s.caps_capacity) {
        s.caps_capacity = std::max(n, 2 * s.caps_capacity);
        glBufferData(GL_SHADER_STORAGE_BUFFER,
                     static_cast<GLsizeiptr>(s.caps_capacity * sizeof(GpuCapsule)), nullptr,
                     GL_DYNAMIC_DRAW);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, s.hits_buffer);
        glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(s.caps_capacity * 4),
                     nullptr, GL_DYNAMIC_READ);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, s.caps_buffer);
      }
      glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(n * sizeof(GpuCapsule)),
                      upload.data());
      glUseProgram(s.program);
      glUniform1ui(s.loc_num_capsules, static_cast<GLuint>(n));
      glUniform1ui(s.loc_num_objects, num_objects);
      glUniform1ui(s.loc_mask_words, static_cast<GLuint>(s.mask_words));
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, env.nodes);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, env.tris);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, env.objects);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, s.masks_buffer);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, s.caps_buffer);
      glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, s.hits_buffer);
      glDispatchCompute(static_cast<GLuint>((n + 63) / 64), 1, 1);
      glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
      s.hits.resize(n);
      glBindBuffer(GL_SHADER_STORAGE_BUFFER, s.hits_buffer);
      glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(n * 4),
                         s.hits.data());
      internal::CheckGl("the swept-volume test");
      for (size_t i = 0; i < n; ++i) {
        (*may_touch)[i] = s.hits[i] == kClearedAnswer && !unusable[i] ? 0 : 1;
      }
    });
  } catch (const GpuError& e) {
    std::lock_guard<std::mutex> lock(s.failure_mutex);
    if (!s.failed.exchange(true)) {
      spdlog::error("GPU backend failed, queries continue on the CPU: {}", e.what());
    }
    may_touch->assign(capsules.size(), 1);
    return false;
  }
  ++s.round_trips;
  s.capsules += static_cast<int64_t>(capsules.size());
  return true;
}

}  // namespace sweptccd::gpu
