#pragma once
// Internal to the entity engine (docs/DESIGN.md, section 5a): an entity as
// one answer sees it - its geometry, its filter rules and a slice of its
// used samples - with no World and no entity index. `sweptccd world` makes
// these over a loaded World (the whole used history), the daemon over a
// due job (the samples its window uses, re-based); the engine cannot tell.

#include <cstddef>
#include <string>
#include <vector>

#include "core/avatar/motion.h"
#include "core/avatar/pose.h"
#include "core/avatar/skeleton.h"
#include "core/scene/environment.h"
#include "core/world/window_split.h"
#include "core/world/world.h"

namespace sweptccd::world {

/// A read-only view of consecutive samples (the caller's storage outlives it).
template <class T>
class SampleSlice {
 public:
  SampleSlice() = default;
  SampleSlice(const std::vector<T>& v) : data_(v.data()), size_(v.size()) {}  // NOLINT
  SampleSlice(const T* data, size_t size) : data_(data), size_(size) {}
  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const T& operator[](size_t k) const { return data_[k]; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + size_; }

 private:
  const T* data_ = nullptr;
  size_t size_ = 0;
};

/// An avatar: its skeleton, motion model and used samples (strictly
/// increasing utimes).
struct AvatarWindow {
  FilterSide who;
  const Skeleton& skeleton;
  MotionModel motion;
  SampleSlice<Pose> samples;
};

/// A tracked object: its mesh (one-object Environment in its own frame) and
/// used samples (strictly increasing utimes).
struct ObjectWindow {
  const std::string& id;
  const Environment& mesh;
  SampleSlice<RigidSample> samples;
};

/// The views of a World's entities (every used sample).
AvatarWindow WindowOfAvatar(const World& world, AvatarIndex a);
ObjectWindow WindowOfObject(const World& world, TrackedObjectIndex o);

/// Largest absolute coordinate of an entity's samples and geometry (its
/// rounding slack scales with it); O(samples).
double EntityScale(const AvatarWindow& entity);
double EntityScale(const ObjectWindow& entity);
double EntityScale(const AvatarEntity& entity);
double EntityScale(const ObjectEntity& entity);

/// The same over the geometry and only the samples the window's pieces use
/// (pieces.front().k to pieces.back().k + 1, clamped to the samples): the
/// scale a window's answer is computed with. It depends on nothing outside
/// the window, so a live service holding only those samples (a slice of
/// the entity's history, re-based so that its first sample is
/// pieces.front().k) answers bit-equal to `sweptccd world`. O(pieces).
/// Precondition: pieces non-empty and from SplitWindow over the samples.
double WindowScale(const AvatarWindow& entity, const std::vector<Piece>& pieces);
double WindowScale(const ObjectWindow& entity, const std::vector<Piece>& pieces);
double WindowScale(const AvatarEntity& entity, const std::vector<Piece>& pieces);
double WindowScale(const ObjectEntity& entity, const std::vector<Piece>& pieces);

/// The largest absolute coordinate of one avatar sample's links, and of a
/// skeleton's link ends: WindowScale of an avatar is the largest of these
/// over the window's samples and its skeleton (a maximum is exact), which
/// callers answering many windows keep per sample.
double SampleScale(const Pose& pose);
double SkeletonScale(const Skeleton& skeleton);

}  // namespace sweptccd::world
