#pragma once
// What `sweptccd query` and `sweptccd world` share, one place per rule: the
// backend flags (--backend, --gpu-device, --require-hardware), --max-links, --threads,
// and the results output (refused when it names an input file).

#include <CLI/CLI.hpp>
#include <fstream>
#include <ostream>
#include <string>
#include <vector>

#include "core/gpu/backend.h"
#include "core/gpu/device_descent.h"
#include "tools/output_paths.h"

namespace sweptccd {

/// The backend flags of a command.
struct BackendFlags {
  gpu::BackendKind backend = gpu::BackendKind::kAuto;
  int gpu_device = -1;  // EGL device index; -1: the first that works.
  bool require_hardware = false;

  gpu::BackendOptions Options() const;
};

/// Adds --backend (parsed into the enum as it is read: a bad name is a
/// parse error; `backend_help` says what it runs), --gpu-device and
/// --require-hardware.
void AddBackendFlags(CLI::App* app, BackendFlags* flags, const std::string& backend_help);

/// Adds --max-links (a positive count: the largest skeleton read).
void AddMaxLinksFlag(CLI::App* app, int* max_links);

/// The most worker threads --threads accepts.
constexpr int kMaxThreads = 1024;

/// Adds --threads (worker threads answering the pairs, 1 to kMaxThreads;
/// *threads should hold the default, DefaultThreadCount()).
void AddThreadsFlag(CLI::App* app, int* threads);

/// Logs (info) what the GPU did for the command: the device descent's
/// counters and times when `descent` is not null, else the backend's
/// dispatches when it is the GPU; nothing on the CPU backend.
void LogGpuWork(const gpu::Backend& backend, const gpu::DeviceDescent* descent);

/// Where a command writes its results (--output): standard output for an
/// empty path, else the file. The constructor refuses (InputError) an output
/// that names one of `inputs` (RefuseClashingPaths), before anything is
/// opened; Open() then opens (truncates) the file, so no input is destroyed
/// before it is read.
class ResultsOutput {
 public:
  ResultsOutput(const std::string& path, const std::vector<NamedPath>& inputs);
  /// Opens the file (standard output: nothing to do). Throws InputError
  /// ("PATH: cannot open the output file").
  void Open();
  ResultsOutput(const ResultsOutput&) = delete;
  ResultsOutput& operator=(const ResultsOutput&) = delete;
  std::ostream& stream() { return *out_; }
  /// Flushes; throws InputError ("PATH: error while writing the results")
  /// when anything written was lost.
  void Finish();

 private:
  std::string path_;
  std::ofstream file_;
  std::ostream* out_;  // Standard output until Open() opens a file.
};

}  // namespace sweptccd
