"""An offscreen OpenGL 4.5 context on Mesa's llvmpipe (EGL, surfaceless), for the comparisons
in this directory. llvmpipe's thread count is LP_NUM_THREADS, set before the context exists.

Without llvmpipe (no Mesa, no PyOpenGL or numpy, no context) the scripts exit with status
`UNAVAILABLE`, so that CI can tell "nothing to compare with" from a difference (status 1)."""

import ctypes
import importlib.util
import os
import sys

UNAVAILABLE = 3


def unavailable(why):
    """Exits with `UNAVAILABLE`, saying why."""
    print(f"llvmpipe unavailable: {why}", file=sys.stderr)
    sys.exit(UNAVAILABLE)


# EGL without a window, and Mesa's software renderer even where a GPU's driver would be picked.
os.environ["PYOPENGL_PLATFORM"] = "egl"
os.environ.setdefault("EGL_PLATFORM", "surfaceless")
os.environ.setdefault("LIBGL_ALWAYS_SOFTWARE", "1")
os.environ.setdefault("GALLIUM_DRIVER", "llvmpipe")

if importlib.util.find_spec("numpy") is None:
    unavailable("no numpy: pip install PyOpenGL numpy")
try:
    from OpenGL import EGL, GL  # noqa: E402  (the platform must be chosen first)
except Exception as e:  # ImportError, or PyOpenGL's errors when libEGL or libOpenGL is missing
    hint = "pip install PyOpenGL; apt-get install libegl1 libopengl0 libgl1-mesa-dri"
    unavailable(f"{type(e).__name__}: {e} ({hint})")
import numpy  # noqa: E402  (found above)

EGL_PLATFORM_SURFACELESS_MESA = 0x31DD


def context():
    """Makes an OpenGL core context current and returns GL_RENDERER and GL_VERSION (the
    renderer must be llvmpipe)."""
    try:
        return _context()
    except Exception as e:  # a missing libEGL shows as any of several PyOpenGL errors
        unavailable(f"no EGL context ({type(e).__name__}: {e})")


def _context():
    display = EGL.eglGetPlatformDisplayEXT(
        EGL_PLATFORM_SURFACELESS_MESA, EGL.EGL_DEFAULT_DISPLAY, None
    )
    major, minor = EGL.EGLint(), EGL.EGLint()
    if not EGL.eglInitialize(display, ctypes.pointer(major), ctypes.pointer(minor)):
        unavailable("eglInitialize failed: is Mesa (libegl-mesa0) installed?")
    EGL.eglBindAPI(EGL.EGL_OPENGL_API)
    config, count = EGL.EGLConfig(), EGL.EGLint()
    wanted = (EGL.EGLint * 3)(EGL.EGL_RENDERABLE_TYPE, EGL.EGL_OPENGL_BIT, EGL.EGL_NONE)
    EGL.eglChooseConfig(display, wanted, ctypes.pointer(config), 1, ctypes.pointer(count))
    attributes = (EGL.EGLint * 7)(
        EGL.EGL_CONTEXT_MAJOR_VERSION, 4,
        EGL.EGL_CONTEXT_MINOR_VERSION, 5,
        EGL.EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL.EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
        EGL.EGL_NONE,
    )
    ctx = EGL.eglCreateContext(display, config, EGL.EGL_NO_CONTEXT, attributes)
    if not ctx or not EGL.eglMakeCurrent(display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, ctx):
        unavailable("cannot create an OpenGL 4.5 core context")
    renderer = GL.glGetString(GL.GL_RENDERER).decode()
    if "llvmpipe" not in renderer:
        unavailable(f"GL_RENDERER is {renderer!r}, not llvmpipe")
    return renderer + ", " + GL.glGetString(GL.GL_VERSION).decode()


def attribute(location, data, normalized=False):
    """A vertex buffer holding `data` (rows of components) bound to `location`."""
    buffer = GL.glGenBuffers(1)
    GL.glBindBuffer(GL.GL_ARRAY_BUFFER, buffer)
    data = numpy.ascontiguousarray(data)
    GL.glBufferData(GL.GL_ARRAY_BUFFER, data.nbytes, data, GL.GL_STATIC_DRAW)
    kind = {numpy.dtype(numpy.float32): GL.GL_FLOAT, numpy.dtype(numpy.uint8): GL.GL_UNSIGNED_BYTE}
    GL.glEnableVertexAttribArray(location)
    GL.glVertexAttribPointer(location, data.shape[1], kind[data.dtype], normalized, 0, None)
    return buffer


def program(vertex, fragment):
    """Compiles and links a vertex + fragment shader pair."""
    prog = GL.glCreateProgram()
    shaders = []
    for kind, source in ((GL.GL_VERTEX_SHADER, vertex), (GL.GL_FRAGMENT_SHADER, fragment)):
        shader = GL.glCreateShader(kind)
        GL.glShaderSource(shader, source)
        GL.glCompileShader(shader)
        if not GL.glGetShaderiv(shader, GL.GL_COMPILE_STATUS):
            raise SystemExit(GL.glGetShaderInfoLog(shader).decode())
        GL.glAttachShader(prog, shader)
        shaders.append(shader)
    GL.glLinkProgram(prog)
    if not GL.glGetProgramiv(prog, GL.GL_LINK_STATUS):
        raise SystemExit(GL.glGetProgramInfoLog(prog).decode())
    for shader in shaders:  # the program keeps what it needs
        GL.glDetachShader(prog, shader)
        GL.glDeleteShader(shader)
    return prog


class Framebuffer:
    """A framebuffer object with one colour attachment (a texture when multisampled, so that
    its samples can be read one by one with `texelFetch`) and optionally a 32-bit float depth
    renderbuffer. Bound and set as the viewport when made; `delete` frees it."""

    def __init__(self, width, height, color_format, depth=False, samples=1):
        self.width, self.height, self.samples = width, height, samples
        self.fbo = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.fbo)
        self.texture = None
        self.renderbuffers = []
        if samples > 1:
            self.texture = GL.glGenTextures(1)
            GL.glBindTexture(GL.GL_TEXTURE_2D_MULTISAMPLE, self.texture)
            GL.glTexImage2DMultisample(
                GL.GL_TEXTURE_2D_MULTISAMPLE, samples, color_format, width, height, GL.GL_TRUE
            )
            GL.glFramebufferTexture2D(
                GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D_MULTISAMPLE,
                self.texture, 0,
            )
        else:
            self._renderbuffer(GL.GL_COLOR_ATTACHMENT0, color_format)
        if depth:
            self._renderbuffer(GL.GL_DEPTH_ATTACHMENT, GL.GL_DEPTH_COMPONENT32F)
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            raise SystemExit(f"framebuffer incomplete: {status:#x}")
        GL.glViewport(0, 0, width, height)

    def _renderbuffer(self, attachment, fmt):
        rb = GL.glGenRenderbuffers(1)
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
        if self.samples > 1:
            GL.glRenderbufferStorageMultisample(
                GL.GL_RENDERBUFFER, self.samples, fmt, self.width, self.height
            )
        else:
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, fmt, self.width, self.height)
        GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, attachment, GL.GL_RENDERBUFFER, rb)
        self.renderbuffers.append(rb)

    def delete(self):
        GL.glDeleteFramebuffers(1, [self.fbo])
        if self.renderbuffers:
            GL.glDeleteRenderbuffers(len(self.renderbuffers), self.renderbuffers)
        if self.texture is not None:
            GL.glDeleteTextures(1, [self.texture])
