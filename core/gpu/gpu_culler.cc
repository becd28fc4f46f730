#include "core/gpu/gpu_culler.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>

#include "core/gpu/cull_combiner.h"
#include "core/gpu/cull_dispatch.h"
#include "core/gpu/gl_api.h"
#include "core/gpu/gpu_environment_buffers.h"

namespace sweptccd::gpu {

namespace {

using internal::GpuCapsule;
using internal::kClearedAnswer;

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

GpuEnvironment::GpuEnvironment(std::shared_ptr<GlContext> context, const Environment& environment,
                               Transfer transfer)
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
        for (int k = 0; k < 3; ++k)
          tris.push_back(static_cast<float>(v[k]));  // Exact: stored as float.
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
    b.dispatch = std::make_unique<internal::CullDispatch>(
        internal::EnvironmentBuffers{b.nodes, b.tris, b.objects, static_cast<GLuint>(num_objects_)},
        transfer);
    transfer_ = b.dispatch->transfer();
  });
  b.combiner = std::make_unique<internal::CullCombiner>(context_.get(), b.dispatch.get());
  spdlog::info("GPU: environment resident, {} objects, {:.1f} MiB; capsules cross by {}",
               num_objects_, uploaded_bytes_ / 1048576.0, TransferName(transfer_));
}

DispatchStats GpuEnvironment::dispatch_stats() const { return buffers_->combiner->stats(); }

void GpuEnvironment::SetGather(int requests, std::chrono::microseconds window) const {
  buffers_->combiner->SetGather(requests, window);
}

GpuEnvironment::~GpuEnvironment() {
  try {
    Buffers* b = buffers_.get();
    context_->Run([b] {
      b->dispatch.reset();
      const GLuint names[] = {b->nodes, b->tris, b->objects};
      glDeleteBuffers(3, names);
    });
  } catch (const GpuError&) {
    // A lost context took its buffers with it; nothing to free on this thread.
    (void)buffers_->dispatch.release();
  }
}

struct GpuCuller::State {
  int num_links = 0;
  std::vector<uint32_t> masks;
  uint32_t masks_offset = 0;  // In the environment's mask buffer.
  std::mutex failure_mutex;
  std::atomic<bool> failed{false};
  std::atomic<int64_t> round_trips{0}, capsules{0};
};

GpuCuller::GpuCuller(std::shared_ptr<const GpuEnvironment> environment,
                     const CollisionFilter& filter, int num_links)
    : env_(std::move(environment)), state_(std::make_unique<State>()) {
  State& s = *state_;
  s.num_links = num_links;
  const int mask_words = std::max(1, (env_->num_objects() + 31) / 32);
  s.masks.assign(static_cast<size_t>(std::max(1, num_links)) * mask_words, 0u);
  for (int l = 0; l < num_links; ++l) {
    for (int o = 0; o < env_->num_objects(); ++o) {
      if (filter.Ignores(LinkIndex(l), ObjectIndex(o)))
        s.masks[l * mask_words + o / 32] |= 1u << (o % 32);
    }
  }
  internal::CullDispatch& dispatch = *env_->buffers().dispatch;
  env_->context().Run([&] { s.masks_offset = dispatch.AddMasks(s.masks); });
}

GpuCuller::~GpuCuller() {
  State* s = state_.get();
  internal::CullDispatch* dispatch = env_->buffers().dispatch.get();
  try {
    env_->context().Run([s, dispatch] { dispatch->RemoveMasks(s->masks_offset, s->masks.size()); });
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
    const double extent =
        std::max({c.a.cwiseAbs().maxCoeff(), c.b.cwiseAbs().maxCoeff(), c.radius});
    if (!(extent <= 1e30) || !(c.radius >= 0)) {
      unusable[i] = 1;
      upload[i] = GpuCapsule{};
      upload[i].meta[0] = static_cast<uint32_t>(c.link);
      continue;
    }
    upload[i] = ToGpu(c);
  }
  for (GpuCapsule& g : upload) g.meta[1] = s.masks_offset;
  std::vector<uint32_t> answers(upload.size());
  try {
    // With the requests of every other thread asking meanwhile: one dispatch.
    env_->buffers().combiner->Cull(upload.data(), upload.size(), answers.data());
    for (size_t i = 0; i < upload.size(); ++i) {
      (*may_touch)[i] = answers[i] == kClearedAnswer && !unusable[i] ? 0 : 1;
    }
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
