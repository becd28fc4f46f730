#include "core/gpu/descent_dispatch.h"

#include <algorithm>
#include <string>

#include "core/gpu/cull_dispatch.h"
#include "core/gpu/gl_context.h"

namespace sweptccd::gpu::internal {

namespace {

// One invocation per work item. The node's capsule is computed here, in
// float, from the track's grid point at the node's midpoint and its growth
// constants, and grown by the error bound of that computation (docs/GPU.md,
// "Why a device clear is a CPU clear"): every input is nonnegative and
// rounded up by the host, each of the four operations of r0 errs by at most
// 2u = 2^-23 of its result (u = 2^-24, the bound GLSL 4.30 section 4.7.1
// gives, the rounding mode open; the product by a power of two is exact but
// for an underflow below 2^-126), so r0 >= (1 - 2^-23)^3 (exact sum) - 2^-126,
// and r = r0 (1 + 2^-16) + 1e-30 (two more roundings) is >= the exact sum.
// The box: lo = (m - r) - (|m| + r) 2^-18 errs by at most 3 2^-23 (|m| + r)
// towards m, less than the 2^-18 (|m| + r) taken off (r >= 1e-20, checked by
// the host, so that product cannot underflow); hi alike. Then the search of
// today's culler (SearchGlsl), unchanged, with the descent's own step cap
// (DescentOptions::max_steps; past it the node "may touch" and its halves
// are tested).
constexpr char kDescentMain[] = R"GLSL(
struct Track { uvec4 meta; vec4 rad; };
layout(std430, binding = 4) readonly buffer Tracks { Track tracks[]; };
layout(std430, binding = 5) readonly buffer Grid { vec4 grid[]; };  // 2 per point: (a, disp), (b, 0)
layout(std430, binding = 6) readonly buffer InItems { uvec2 in_items[]; };
layout(std430, binding = 7) writeonly buffer OutItems { uvec2 out_items[]; };
layout(std430, binding = 8) buffer Counters { uint counters[]; };  // queue; per pair: pushed, flags
layout(std430, binding = 9) buffer Cleared { uint cleared[]; };    // per track

uniform uint u_num_items;
uniform uint u_num_tracks;
uniform uint u_grid_levels;
uniform uint u_stop_depth;
uniform uint u_pair_budget;
uniform uint u_capacity;

// Half the width of a node at each depth: powers of two, exact.
const float kHalfWidth[5] = float[](0.5, 0.25, 0.125, 0.0625, 0.03125);
const float kRadiusGrow = 1.0 + 1.0 / 65536.0;
const float kBoxGrow = 1.0 / 262144.0;

void main() {
  uint id = gl_GlobalInvocationID.x;
  if (id >= u_num_items) return;
  uvec2 item = in_items[id];
  uint t = item.x;
  uint depth = item.y >> 24u;
  uint k = item.y & 0xFFFFFFu;
  if (t >= u_num_tracks || depth >= u_stop_depth || depth >= u_grid_levels || depth >= 5u ||
      k >= (1u << depth)) {
    return;
  }
  Track tr = tracks[t];
  // The node's midpoint, (2k + 1) 2^-(depth + 1), on the grid of 2^u_grid_levels steps.
  uint j = tr.meta.w + ((2u * k + 1u) << (u_grid_levels - depth - 1u));
  vec4 ga = grid[2u * j];
  vec4 gb = grid[2u * j + 1u];
  vec3 a = ga.xyz, b = gb.xyz;
  precise float r0 = ((tr.rad.x + tr.rad.y * kHalfWidth[depth]) + tr.rad.z) + ga.w;
  precise float r = r0 * kRadiusGrow + 1e-30;
  vec3 m_lo = min(a, b), m_hi = max(a, b);
  precise vec3 lo = (m_lo - r) - (abs(m_lo) + r) * kBoxGrow;
  precise vec3 hi = (m_hi + r) + (abs(m_hi) + r) * kBoxGrow;
  if (Search(a, b, r, lo, hi, tr.meta.x, tr.meta.y) == kCleared) {
    atomicOr(cleared[t], 1u << ((1u << depth) - 1u + k));
    return;
  }
  if (depth + 1u >= u_stop_depth) return;
  uint pair = tr.meta.z;
  if (atomicAdd(counters[1u + 2u * pair], 2u) + 2u > u_pair_budget) {
    atomicOr(counters[2u + 2u * pair], 1u);  // kOverPairBudget
    return;
  }
  // Slots come in twos and the capacity is even: slot < capacity leaves room for both.
  uint slot = atomicAdd(counters[0], 2u);
  if (slot >= u_capacity) {
    atomicOr(counters[2u + 2u * pair], 2u);  // kOverCapacity
    return;
  }
  uint child = ((depth + 1u) << 24u) | (2u * k);
  out_items[slot] = uvec2(t, child);
  out_items[slot + 1u] = uvec2(t, child + 1u);
}
)GLSL";

void Fill(GLuint buffer, const void* data, size_t bytes) {
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
  glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(std::max<size_t>(bytes, 16)),
               nullptr, GL_DYNAMIC_DRAW);
  if (bytes > 0 && data != nullptr) {
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(bytes), data);
  }
}

}  // namespace

DescentDispatch::DescentDispatch(GLuint nodes, GLuint tris, GLuint objects, GLuint num_objects)
    : nodes_(nodes), tris_(tris), objects_(objects), num_objects_(num_objects) {
  program_ = CompileProgram((ShaderHead() + SearchGlsl() + kDescentMain).c_str());
  const char* names[9] = {"u_num_objects", "u_mask_words",  "u_num_items",
                          "u_num_tracks",  "u_grid_levels", "u_stop_depth",
                          "u_pair_budget", "u_capacity",    "u_max_steps"};
  for (int i = 0; i < 9; ++i) loc_[i] = glGetUniformLocation(program_, names[i]);
  glGenBuffers(6, buffers_);
  CheckGl("creating the device descent");
}

DescentDispatch::~DescentDispatch() {
  glDeleteBuffers(6, buffers_);
  glDeleteProgram(program_);
}

int DescentDispatch::Run(const std::vector<DescentTrack>& tracks, const DescentPoint* grid,
                         size_t grid_size, const std::vector<DescentItem>& items,
                         const DescentLevels& levels, GLuint masks, uint32_t mask_words,
                         std::vector<uint32_t>* pushed, std::vector<uint32_t>* flags,
                         std::vector<uint32_t>* cleared, int64_t* tested) {
  if (items.empty() || tracks.empty()) return 0;
  const size_t num_pairs = pushed->size();
  const uint32_t capacity = std::max<uint32_t>(2, levels.capacity & ~1u);
  GLuint& tracks_buf = buffers_[0];
  GLuint& grid_buf = buffers_[1];
  GLuint queue[2] = {buffers_[2], buffers_[3]};
  GLuint& counters_buf = buffers_[4];
  GLuint& cleared_buf = buffers_[5];
  Fill(tracks_buf, tracks.data(), tracks.size() * sizeof(DescentTrack));
  Fill(grid_buf, grid, grid_size * sizeof(DescentPoint));
  const size_t queue_items = std::max<size_t>(items.size(), capacity);
  Fill(queue[0], nullptr, queue_items * sizeof(DescentItem));
  glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0,
                  static_cast<GLsizeiptr>(items.size() * sizeof(DescentItem)), items.data());
  Fill(queue[1], nullptr, queue_items * sizeof(DescentItem));
  std::vector<uint32_t> counters(1 + 2 * num_pairs, 0u);
  for (size_t p = 0; p < num_pairs; ++p) counters[1 + 2 * p] = (*pushed)[p];
  Fill(counters_buf, counters.data(), counters.size() * 4);
  std::vector<uint32_t> zeros(tracks.size(), 0u);
  Fill(cleared_buf, zeros.data(), zeros.size() * 4);

  glUseProgram(program_);
  glUniform1ui(loc_[0], num_objects_);
  glUniform1ui(loc_[1], mask_words);
  glUniform1ui(loc_[3], static_cast<GLuint>(tracks.size()));
  glUniform1ui(loc_[4], static_cast<GLuint>(levels.grid_levels));
  glUniform1ui(loc_[5], static_cast<GLuint>(levels.stop_depth));
  glUniform1ui(loc_[6], levels.pair_budget);
  glUniform1ui(loc_[7], capacity);
  glUniform1ui(loc_[8], std::clamp<uint32_t>(levels.max_steps, 1, kMaxSearchSteps));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, nodes_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, tris_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, objects_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, masks);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, tracks_buf);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, grid_buf);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 8, counters_buf);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 9, cleared_buf);
  size_t n = items.size();
  int in = 0, dispatches = 0;
  // Each level's items are one depth deeper than the last's: at most
  // stop_depth levels.
  while (n > 0 && dispatches <= levels.stop_depth) {
    const uint32_t zero = 0;
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, counters_buf);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, 4, &zero);
    glUniform1ui(loc_[2], static_cast<GLuint>(n));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, queue[in]);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, queue[1 - in]);
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    glDispatchCompute(static_cast<GLuint>((n + 63) / 64), 1, 1);
    ++dispatches;
    *tested += static_cast<int64_t>(n);
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
    uint32_t count = 0;
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, counters_buf);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, 4, &count);
    n = std::min<size_t>(count, capacity);
    in = 1 - in;
  }
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, counters_buf);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(counters.size() * 4),
                     counters.data());
  for (size_t p = 0; p < num_pairs; ++p) {
    (*pushed)[p] = counters[1 + 2 * p];
    (*flags)[p] |= counters[2 + 2 * p];
  }
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, cleared_buf);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(zeros.size() * 4),
                     zeros.data());
  for (size_t t = 0; t < tracks.size(); ++t) (*cleared)[t] |= zeros[t];
  CheckGl("the device descent");
  return dispatches;
}

}  // namespace sweptccd::gpu::internal
