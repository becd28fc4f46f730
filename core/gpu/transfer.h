#pragma once
// How the swept-volume test's capsules go up and its answers come back
// (core/gpu/cull_dispatch.h; docs/GPU.md, "The round trip").

namespace sweptccd::gpu {

enum class Transfer {
  kBest,        // Persistent mapped buffers where the context has them, else read-back.
  kReadBack,    // glBufferSubData up, glGetBufferSubData down (the way before issue 30).
  kPersistent,  // Persistent coherent mapped buffers (glBufferStorage) and a fence.
};

/// "best", "read-back" or "persistent mapped buffers and a fence".
const char* TransferName(Transfer transfer);

}  // namespace sweptccd::gpu
