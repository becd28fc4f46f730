// The headless EGL context: creation without a display server, the
// surfaceless fallback, work handed over from other threads, loss and clean
// shutdown. Runs on whatever EGL offers (Mesa llvmpipe in CI); never skipped.

#include "core/gpu/gl_context.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/gpu/gl_api.h"

namespace sweptccd::gpu {
namespace {

void ExpectUsable(const GlContext& context) {
  const GlContextInfo& info = context.info();
  EXPECT_GE(info.major * 10 + info.minor, 43) << info.Summary();
  EXPECT_FALSE(info.renderer.empty());
  EXPECT_FALSE(info.vendor.empty());
  EXPECT_FALSE(info.glsl_version.empty());
  EXPECT_TRUE(info.display.rfind("EGL device ", 0) == 0 || info.display == "Mesa surfaceless")
      << info.display;
}

TEST(GlContextTest, CreatesWithNoDisplayVariable) {
  ::unsetenv("DISPLAY");
  ::unsetenv("WAYLAND_DISPLAY");
  GlContext context;
  ExpectUsable(context);
  std::printf("context: %s\n", context.info().Summary().c_str());
  // The context really computes: a compute shader writes its invocation ids.
  std::vector<GLuint> out(256, 0);
  context.Run([&] {
    const GLuint program = internal::CompileProgram(R"(#version 430
layout(local_size_x = 64) in;
layout(std430, binding = 0) writeonly buffer Out { uint v[]; };
void main() { v[gl_GlobalInvocationID.x] = gl_GlobalInvocationID.x * 3u + 1u; })");
    GLuint buffer = 0;
    glGenBuffers(1, &buffer);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
    glBufferData(GL_SHADER_STORAGE_BUFFER, 256 * 4, nullptr, GL_DYNAMIC_READ);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, buffer);
    glUseProgram(program);
    glDispatchCompute(4, 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, 256 * 4, out.data());
    glDeleteBuffers(1, &buffer);
    glDeleteProgram(program);
    internal::CheckGl("test dispatch");
  });
  for (GLuint i = 0; i < 256; ++i) ASSERT_EQ(out[i], i * 3 + 1) << i;
}

TEST(GlContextTest, SurfacelessFallback) {
  GlContextOptions options;
  options.surfaceless_only = true;
  GlContext context(options);
  ExpectUsable(context);
  EXPECT_EQ(context.info().display, "Mesa surfaceless");
}

TEST(GlContextTest, DeviceIndexOutOfRangeIsRefused) {
  GlContextOptions options;
  options.device_index = 31;
  try {
    GlContext context(options);
    FAIL() << "device 31 accepted: " << context.info().Summary();
  } catch (const GpuError& e) {
    EXPECT_NE(std::string(e.what()).find("device 31"), std::string::npos) << e.what();
  }
}

TEST(GlContextTest, RequireHardwareRefusesSoftware) {
  GlContext any;
  GlContextOptions options;
  options.require_hardware = true;
  if (any.info().software) {
    // Only a software renderer here (llvmpipe in CI): it must be refused,
    // and the message must say why.
    try {
      GlContext hardware(options);
      EXPECT_FALSE(hardware.info().software) << hardware.info().Summary();
    } catch (const GpuError& e) {
      EXPECT_NE(std::string(e.what()).find("software renderer"), std::string::npos) << e.what();
    }
  } else {
    GlContext hardware(options);
    EXPECT_FALSE(hardware.info().software);
  }
}

TEST(GlContextTest, WorkFromOtherThreadsRunsOnTheOwner) {
  GlContext context;
  EXPECT_FALSE(context.OnOwnerThread());
  std::atomic<int> ran{0}, on_owner{0}, current{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 50; ++i) {
        context.Run([&] {
          ++ran;
          if (context.OnOwnerThread()) ++on_owner;
          if (eglGetCurrentContext() != EGL_NO_CONTEXT && glGetString(GL_RENDERER) != nullptr) {
            ++current;
          }
          // Work handed over from the owner thread itself runs inline.
          context.Run([&] { ++ran; });
        });
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(ran, 400);
  EXPECT_EQ(on_owner, 200);
  EXPECT_EQ(current, 200);
  // An exception thrown by the work reaches the caller; the context goes on.
  EXPECT_THROW(context.Run([] { throw std::runtime_error("from the work"); }), std::runtime_error);
  int after = 0;
  context.Run([&] { after = 1; });
  EXPECT_EQ(after, 1);
  EXPECT_FALSE(context.lost());
}

TEST(GlContextTest, LossIsReportedAndSticky) {
  GlContext context;
  // Simulate a lost context: it stops being current on its owner thread.
  EXPECT_THROW(context.Run([] {
    eglMakeCurrent(eglGetCurrentDisplay(), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  }),
               GpuError);
  EXPECT_TRUE(context.lost());
  bool ran = false;
  EXPECT_THROW(context.Run([&] { ran = true; }), GpuError);
  EXPECT_FALSE(ran);
}

TEST(GlContextTest, CleanShutdownFinishesHandedOverWork) {
  for (int round = 0; round < 3; ++round) {
    std::atomic<int> done{0};
    {
      GlContext context;
      std::vector<std::thread> threads;
      for (int t = 0; t < 3; ++t) {
        threads.emplace_back([&] {
          for (int i = 0; i < 20; ++i) context.Run([&] { glFinish(); ++done; });
        });
      }
      for (std::thread& t : threads) t.join();
    }  // Destroyed here: context, display and owner thread released.
    EXPECT_EQ(done, 60) << "round " << round;
  }
  // Two contexts at once, each with its own owner thread.
  GlContext a, b;
  int x = 0, y = 0;
  a.Run([&] { x = 1; });
  b.Run([&] { y = 2; });
  EXPECT_EQ(x + y, 3);
}

}  // namespace
}  // namespace sweptccd::gpu
