#include "tools/command_common.h"

#include <spdlog/spdlog.h>

#include <iostream>

#include "core/avatar/skeleton.h"
#include "core/errors.h"

namespace sweptccd {

gpu::BackendOptions BackendFlags::Options() const {
  gpu::BackendOptions options;
  options.backend = backend;
  options.device_index = gpu_device;
  options.require_hardware = require_hardware;
  return options;
}

void AddBackendFlags(CLI::App* app, BackendFlags* flags, const std::string& backend_help) {
  app->add_option_function<std::string>(
      "--backend",
      [flags](const std::string& name) {
        try {
          flags->backend = gpu::ParseBackendKind(name, "--backend");
        } catch (const InputError& e) {
          throw CLI::ValidationError(e.what());
        }
      },
      backend_help);
  app->add_option("--gpu-device", flags->gpu_device, "EGL device index for the GPU backend");
  app->add_flag("--require-hardware", flags->require_hardware,
                "GPU backend: refuse software renderers (llvmpipe)");
}

void LogGpuWork(const gpu::Backend& backend, const gpu::DeviceDescent* descent) {
  if (descent != nullptr) {
    const gpu::DescentStats d = descent->stats();
    spdlog::info(
        "GPU device descent: {} batches, {} dispatches, {} intervals tested, {} cleared, {} "
        "pairs over budget; {}",
        d.batches, d.dispatches, d.items, d.cleared, d.over_budget, gpu::DescentTimes(d));
  } else if (backend.gpu()) {
    spdlog::info("GPU: {}", backend.DispatchSummary());
  }
}

void AddMaxLinksFlag(CLI::App* app, int* max_links) {
  app->add_option("--max-links", *max_links,
                  "Largest skeleton, links (default " + std::to_string(kDefaultMaxLinks) + ")")
      ->check(CLI::PositiveNumber);
}

void AddThreadsFlag(CLI::App* app, int* threads) {
  app->add_option("--threads", *threads,
                  "Worker threads answering the pairs (default: the number of cores, " +
                      std::to_string(*threads) + "); the records are the same for any number")
      ->check(CLI::Range(1, kMaxThreads));
}

ResultsOutput::ResultsOutput(const std::string& path, const std::vector<NamedPath>& inputs)
    : path_(path), out_(&std::cout) {
  RefuseClashingPaths(inputs, {{"--output", path}});
}

void ResultsOutput::Open() {
  if (path_.empty()) return;
  file_.open(path_, std::ios::binary | std::ios::trunc);
  if (!file_) throw InputError(path_ + ": cannot open the output file");
  out_ = &file_;
}

void ResultsOutput::Finish() {
  out_->flush();
  if (!*out_) {
    throw InputError((path_.empty() ? std::string("standard output") : path_) +
                     ": error while writing the results");
  }
}

}  // namespace sweptccd
