#pragma once
// Private to core/gpu: the EGL and OpenGL core headers. OpenGL entry points
// come from GLVND's libOpenGL (every core function up to 4.6 is exported), so
// no loader is needed; extension entry points go through eglGetProcAddress.

#include <EGL/egl.h>
#include <EGL/eglext.h>
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <string>

namespace sweptccd::gpu::internal {

/// Compiles and links one compute or vertex+fragment program; throws GpuError
/// with the driver's log. Must run on the context's owner thread.
GLuint CompileProgram(const char* compute_source);
GLuint CompileProgram(const char* vertex_source, const char* fragment_source);

/// Throws GpuError naming `what` when glGetError reports an error.
void CheckGl(const char* what);

}  // namespace sweptccd::gpu::internal
