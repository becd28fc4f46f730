#pragma once
// Private to core/gpu: one compute dispatch of the swept-volume test (the
// shader, its program, the capsule and answer buffers, the collision
// filters' object masks) for one resident environment. Every method runs on
// the context's owner thread (inside GlContext::Run); nothing here locks.
//
// How capsules go up and answers come back (issue 30, docs/GPU.md, "The
// round trip"): with persistent mapped buffers (glBufferStorage with
// GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT, OpenGL 4.4 or
// GL_ARB_buffer_storage) the host writes the capsules straight into memory
// the GPU reads, and after the dispatch a fence (glFenceSync /
// glClientWaitSync) says when the answers in the mapped answer buffer are
// final; otherwise (read-back) glBufferSubData up and glGetBufferSubData
// down, a stall of the pipeline per round trip.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/gpu/gl_api.h"
#include "core/gpu/transfer.h"

namespace sweptccd::gpu::internal {

/// A capsule as the shader reads it (std430): a_r = endpoint a and radius,
/// b = endpoint b, lo/hi = its box, meta = (link, mask table offset in words,
/// 0, 0).
struct GpuCapsule {
  float a_r[4];
  float b[4];
  float lo[4];
  float hi[4];
  uint32_t meta[4];
};
static_assert(sizeof(GpuCapsule) == 80, "std430 layout of Capsule");

/// The shader's answer for a capsule proved clear (kCleared in the shader);
/// any other value means "may touch".
constexpr uint32_t kClearedAnswer = 0xC1EA4EDu;

/// The search's step cap (u_max_steps of SearchGlsl): past it an invocation
/// answers "may touch". kMaxSearchSteps: the most a host may set, far below
/// llvmpipe's 65,535 loop iterations per group of invocations (cull_dispatch.cc,
/// "The whole search is one loop"); kCullMaxSteps: the culler's.
constexpr uint32_t kMaxSearchSteps = 16384;
constexpr uint32_t kCullMaxSteps = 16384;

using gpu::Transfer;

/// The environment's buffers the shader reads.
struct EnvironmentBuffers {
  GLuint nodes = 0, tris = 0, objects = 0;
  GLuint num_objects = 0;
};

/// The compute shaders' first lines (#version, the work group size), and
/// the swept-volume search they share: bindings 0-3 (nodes, triangles,
/// objects, masks), uniforms u_num_objects, u_mask_words and u_max_steps
/// (the step cap, 1 to kMaxSearchSteps), and
/// `uint Search(vec3 a, vec3 b, float r, vec3 lo, vec3 hi, uint link, uint
/// mask_base)`, kCleared (0xC1EA4ED) only for a capsule proved clear.
std::string ShaderHead();
std::string SearchGlsl();

class CullDispatch {
 public:
  /// Compiles the program and makes the buffers; `transfer` kBest or
  /// kPersistent uses persistent buffers when the context offers them (else
  /// read-back, logged). Throws GpuError.
  CullDispatch(const EnvironmentBuffers& env, Transfer transfer);
  /// Frees the GL objects (the context must still be current).
  ~CullDispatch();
  CullDispatch(const CullDispatch&) = delete;
  CullDispatch& operator=(const CullDispatch&) = delete;

  /// The way in use: kReadBack or kPersistent.
  Transfer transfer() const { return transfer_; }

  /// Stores a filter's per-link object masks (`words` per link, link-major);
  /// returns the table's offset in words, for the capsules' meta[1]. Freed
  /// spans are reused. Throws GpuError.
  uint32_t AddMasks(const std::vector<uint32_t>& masks);
  /// Gives back a table (its offset and size) for reuse.
  void RemoveMasks(uint32_t offset, size_t size);
  /// The buffer of every filter's masks (binding 3 of SearchGlsl) and the
  /// words per link in it (u_mask_words).
  GLuint masks_buffer() const { return masks_buffer_; }
  uint32_t mask_words() const { return mask_words_; }

  /// Tests `n` capsules in one dispatch; answers[i] is the shader's word for
  /// capsule i (kClearedAnswer or anything else). Throws GpuError.
  void Run(const GpuCapsule* capsules, size_t n, uint32_t* answers);

 private:
  void Reserve(size_t n);  // Capacity for n capsules.
  void FreeIo();

  EnvironmentBuffers env_;
  Transfer transfer_;
  GLuint program_ = 0;
  GLint loc_num_capsules_ = -1, loc_num_objects_ = -1, loc_mask_words_ = -1, loc_max_steps_ = -1;
  uint32_t mask_words_ = 1;
  // The mask tables of every filter, host copy of the buffer.
  GLuint masks_buffer_ = 0;
  std::vector<uint32_t> masks_;
  size_t masks_capacity_ = 0;                            // Words allocated on the GPU.
  std::vector<std::pair<uint32_t, size_t>> free_spans_;  // Offset, words.
  // Capsules up, answers down.
  GLuint caps_buffer_ = 0, hits_buffer_ = 0;
  size_t capacity_ = 0;                // Capsules.
  GpuCapsule* mapped_caps_ = nullptr;  // Persistent: the mapped buffers.
  uint32_t* mapped_hits_ = nullptr;
};

}  // namespace sweptccd::gpu::internal
