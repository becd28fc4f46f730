#pragma once
// Private to core/gpu: what a GpuEnvironment holds on the GPU (its GL names,
// the swept-volume test's dispatch and the combiner of requests). Shared by
// the culler (gpu_culler.cc) and the device descent (device_descent.cc).

#include <memory>

#include "core/gpu/cull_combiner.h"
#include "core/gpu/cull_dispatch.h"
#include "core/gpu/gl_api.h"
#include "core/gpu/gpu_culler.h"

namespace sweptccd::gpu {

struct GpuEnvironment::Buffers {
  GLuint nodes = 0, tris = 0, objects = 0;
  // The program, the filters' masks and the capsule buffers (owner thread).
  std::unique_ptr<internal::CullDispatch> dispatch;
  // Every culler's requests, from every thread, coalesced into dispatches.
  std::unique_ptr<internal::CullCombiner> combiner;
};

}  // namespace sweptccd::gpu
