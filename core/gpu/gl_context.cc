#include "core/gpu/gl_context.h"

#include <dlfcn.h>
#include <link.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <exception>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include "core/gpu/gl_api.h"

namespace sweptccd::gpu {

namespace {

std::string EglErrorName(EGLint error) {
  switch (error) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    default: return "EGL error 0x" + std::to_string(error);
  }
}

bool HasExtension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

std::string GlString(GLenum name) {
  const GLubyte* s = glGetString(name);
  return s ? reinterpret_cast<const char*>(s) : "";
}

bool IsSoftwareRenderer(const std::string& renderer) {
  for (const char* name : {"llvmpipe", "softpipe", "swrast", "Software Rasterizer"}) {
    if (renderer.find(name) != std::string::npos) return true;
  }
  return false;
}

#if defined(__SANITIZE_ADDRESS__)
// Sanitizer builds only (tools/sanitize.sh): the EGL vendor library dlcloses
// Mesa's driver at eglTerminate, and a block the driver still points to from
// its own globals then looks leaked to LeakSanitizer at exit, allocated from
// an "<unknown module>" that no suppression can name (128 bytes, seen in
// every process that ran a GPU calibration). Taking one more reference to
// each driver loaded now (never released) keeps it mapped, so the leak
// check sees through it and tools/lsan_suppressions.txt names only what is
// really the driver's. Release builds do nothing here.
void KeepDriversMapped() {
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void*) {
        const char* name = info->dlpi_name;
        if (name != nullptr && std::strstr(name, "_dri.so") != nullptr) {
          dlopen(name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
        }
        return 0;
      },
      nullptr);
}
#else
void KeepDriversMapped() {}
#endif

}  // namespace

std::string GlContextInfo::Summary() const {
  return renderer + " (" + vendor + "), OpenGL " + version + ", " + display;
}

struct GlContext::Impl {
  GlContextOptions options;
  GlContextInfo info;
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  GLenum (*get_reset_status)() = nullptr;  // GL_KHR_robustness, when offered.

  std::thread owner;
  std::thread::id owner_id;
  std::mutex mutex;
  std::condition_variable wake;
  std::deque<std::packaged_task<void()>> queue;
  bool stopping = false;
  std::atomic<bool> lost{false};

  // Owner thread: make the context, serve the queue, tear down.
  void Main(std::promise<void>* ready);
  void Create();
  // Tries one display; on failure returns the reason and leaves nothing open.
  std::string TryDisplay(EGLDisplay dpy, const std::string& label);
  void Destroy();
  void CheckLost();
};

std::string GlContext::Impl::TryDisplay(EGLDisplay dpy, const std::string& label) {
  if (dpy == EGL_NO_DISPLAY) return label + ": no display (" + EglErrorName(eglGetError()) + ")";
  EGLint major = 0, minor = 0;
  if (!eglInitialize(dpy, &major, &minor)) {
    return label + ": eglInitialize failed (" + EglErrorName(eglGetError()) + ")";
  }
  KeepDriversMapped();
  auto fail = [&](const std::string& why) {
    if (context != EGL_NO_CONTEXT) {
      eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(dpy, context);
      context = EGL_NO_CONTEXT;
    }
    eglTerminate(dpy);
    return label + ": " + why;
  };
  const char* extensions = eglQueryString(dpy, EGL_EXTENSIONS);
  if (!HasExtension(extensions, "EGL_KHR_surfaceless_context")) {
    return fail("no EGL_KHR_surfaceless_context");
  }
  if (!eglBindAPI(EGL_OPENGL_API)) return fail("eglBindAPI(EGL_OPENGL_API) failed");
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!HasExtension(extensions, "EGL_KHR_no_config_context")) {
    const EGLint attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                              EGL_OPENGL_BIT, EGL_NONE};
    EGLint count = 0;
    if (!eglChooseConfig(dpy, attribs, &config, 1, &count) || count < 1) {
      return fail("no EGL config with OpenGL support");
    }
  }
  const bool robust = HasExtension(extensions, "EGL_EXT_create_context_robustness");
  for (const bool with_robustness : {true, false}) {
    if (with_robustness && !robust) continue;
    std::vector<EGLint> attribs = {EGL_CONTEXT_MAJOR_VERSION, 4,
                                   EGL_CONTEXT_MINOR_VERSION, 3,
                                   EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                   EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT};
    if (with_robustness) {
      attribs.insert(attribs.end(), {EGL_CONTEXT_OPENGL_RESET_NOTIFICATION_STRATEGY_EXT,
                                     EGL_LOSE_CONTEXT_ON_RESET_EXT});
    }
    attribs.push_back(EGL_NONE);
    context = eglCreateContext(dpy, config, EGL_NO_CONTEXT, attribs.data());
    if (context != EGL_NO_CONTEXT) break;
  }
  if (context == EGL_NO_CONTEXT) {
    return fail("no OpenGL 4.3 core context (" + EglErrorName(eglGetError()) + ")");
  }
  if (!eglMakeCurrent(dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    return fail("eglMakeCurrent failed (" + EglErrorName(eglGetError()) + ")");
  }
  GlContextInfo found;
  found.display = label;
  found.vendor = GlString(GL_VENDOR);
  found.renderer = GlString(GL_RENDERER);
  found.version = GlString(GL_VERSION);
  found.glsl_version = GlString(GL_SHADING_LANGUAGE_VERSION);
  glGetIntegerv(GL_MAJOR_VERSION, &found.major);
  glGetIntegerv(GL_MINOR_VERSION, &found.minor);
  found.software = IsSoftwareRenderer(found.renderer);
  if (found.major * 10 + found.minor < 43) {
    return fail("OpenGL " + found.version + " is older than 4.3 (" + found.renderer + ")");
  }
  if (options.require_hardware && found.software) {
    return fail("software renderer " + found.renderer + " refused (require_hardware)");
  }
  display = dpy;
  info = found;
  get_reset_status =
      reinterpret_cast<GLenum (*)()>(eglGetProcAddress("glGetGraphicsResetStatus"));
  if (get_reset_status == nullptr) {
    get_reset_status =
        reinterpret_cast<GLenum (*)()>(eglGetProcAddress("glGetGraphicsResetStatusKHR"));
  }
  return {};
}

void GlContext::Impl::Create() {
  std::vector<std::string> tried;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (get_platform_display == nullptr) {
    throw GpuError("no EGL display: eglGetPlatformDisplayEXT is missing (EGL_EXT_platform_base)");
  }
  if (!options.surfaceless_only) {
    auto query_devices =
        reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    const bool enumerable = HasExtension(client, "EGL_EXT_device_enumeration") ||
                            HasExtension(client, "EGL_EXT_device_base");
    if (!enumerable || query_devices == nullptr ||
        !HasExtension(client, "EGL_EXT_platform_device")) {
      tried.push_back("EGL devices: no EGL_EXT_device_enumeration with EGL_EXT_platform_device");
    } else {
      EGLDeviceEXT devices[32];
      EGLint count = 0;
      if (!query_devices(32, devices, &count)) count = 0;
      if (count == 0) tried.push_back("EGL devices: none found");
      if (options.device_index >= count) {
        throw GpuError("EGL device " + std::to_string(options.device_index) +
                       " does not exist: " + std::to_string(count) + " device(s) found");
      }
      for (int i = 0; i < count; ++i) {
        if (options.device_index >= 0 && i != options.device_index) continue;
        const std::string label =
            "EGL device " + std::to_string(i) + " of " + std::to_string(count);
        const std::string why = TryDisplay(
            get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr), label);
        if (why.empty()) return;
        tried.push_back(why);
      }
      if (options.device_index >= 0) {
        throw GpuError("no OpenGL context on the configured device: " + tried.back());
      }
    }
  }
  if (!HasExtension(client, "EGL_MESA_platform_surfaceless")) {
    tried.push_back("Mesa surfaceless: EGL_MESA_platform_surfaceless not offered");
  } else {
    const std::string why = TryDisplay(
        get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
        "Mesa surfaceless");
    if (why.empty()) return;
    tried.push_back(why);
  }
  std::string message = "no headless OpenGL 4.3 context:";
  for (const std::string& t : tried) message += " [" + t + "]";
  throw GpuError(message);
}

void GlContext::Impl::Destroy() {
  if (display == EGL_NO_DISPLAY) return;
  eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
  eglTerminate(display);
  eglReleaseThread();
  context = EGL_NO_CONTEXT;
  display = EGL_NO_DISPLAY;
}

void GlContext::Impl::CheckLost() {
  if (lost) throw GpuError("the OpenGL context was lost");
  if (get_reset_status != nullptr && get_reset_status() != GL_NO_ERROR) {
    lost = true;
    throw GpuError("the OpenGL context was lost (graphics reset reported by the driver)");
  }
  if (eglGetCurrentContext() != context) {
    lost = true;
    throw GpuError("the OpenGL context is no longer current (" + EglErrorName(eglGetError()) + ")");
  }
}

void GlContext::Impl::Main(std::promise<void>* ready) {
  try {
    Create();
  } catch (...) {
    ready->set_exception(std::current_exception());
    return;
  }
  ready->set_value();
  for (;;) {
    std::packaged_task<void()> task;
    {
      std::unique_lock<std::mutex> lock(mutex);
      wake.wait(lock, [&] { return stopping || !queue.empty(); });
      if (queue.empty()) break;  // Stopping, and every handed-over task is done.
      task = std::move(queue.front());
      queue.pop_front();
    }
    task();
  }
  Destroy();
}

GlContext::GlContext(const GlContextOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  std::promise<void> ready;
  std::future<void> made = ready.get_future();
  impl_->owner = std::thread([this, &ready] { impl_->Main(&ready); });
  impl_->owner_id = impl_->owner.get_id();
  try {
    made.get();
  } catch (...) {
    impl_->owner.join();
    throw;
  }
  spdlog::info("GPU: {} (GLSL {})", impl_->info.Summary(), impl_->info.glsl_version);
}

GlContext::~GlContext() {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->stopping = true;
  }
  impl_->wake.notify_all();
  impl_->owner.join();
}

const GlContextInfo& GlContext::info() const { return impl_->info; }

bool GlContext::lost() const { return impl_->lost; }

bool GlContext::OnOwnerThread() const { return std::this_thread::get_id() == impl_->owner_id; }

void GlContext::Run(const std::function<void()>& work) {
  Impl& impl = *impl_;
  auto wrapped = [&impl, &work] {
    impl.CheckLost();
    work();
    impl.CheckLost();
  };
  if (OnOwnerThread()) {
    wrapped();
    return;
  }
  std::packaged_task<void()> task(wrapped);
  std::future<void> done = task.get_future();
  {
    std::lock_guard<std::mutex> lock(impl.mutex);
    if (impl.lost) throw GpuError("the OpenGL context was lost");
    impl.queue.push_back(std::move(task));
  }
  impl.wake.notify_one();
  done.get();
}

namespace internal {

namespace {

GLuint CompileShader(GLenum kind, const char* source) {
  const GLuint shader = glCreateShader(kind);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    char log[4096] = {};
    glGetShaderInfoLog(shader, sizeof(log) - 1, nullptr, log);
    glDeleteShader(shader);
    throw GpuError(std::string("shader compilation failed: ") + log);
  }
  return shader;
}

GLuint LinkProgram(const std::vector<GLuint>& shaders) {
  const GLuint program = glCreateProgram();
  for (GLuint s : shaders) glAttachShader(program, s);
  glLinkProgram(program);
  for (GLuint s : shaders) glDeleteShader(s);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    char log[4096] = {};
    glGetProgramInfoLog(program, sizeof(log) - 1, nullptr, log);
    glDeleteProgram(program);
    throw GpuError(std::string("program link failed: ") + log);
  }
  return program;
}

}  // namespace

GLuint CompileProgram(const char* compute_source) {
  return LinkProgram({CompileShader(GL_COMPUTE_SHADER, compute_source)});
}

GLuint CompileProgram(const char* vertex_source, const char* fragment_source) {
  return LinkProgram({CompileShader(GL_VERTEX_SHADER, vertex_source),
                      CompileShader(GL_FRAGMENT_SHADER, fragment_source)});
}

void CheckGl(const char* what) {
  const GLenum error = glGetError();
  if (error != GL_NO_ERROR) {
    throw GpuError(std::string(what) + ": OpenGL error 0x" + [&] {
      char hex[16];
      std::snprintf(hex, sizeof(hex), "%04x", error);
      return std::string(hex);
    }());
  }
}

}  // namespace internal

}  // namespace sweptccd::gpu
