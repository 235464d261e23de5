"""Times Mesa's llvmpipe on the triangles of `trirast bench`, for ratios measured side by
side on the same machine in the same minutes (this VM's speed drifts by up to 1.6x over a day).

    trirast bench [SCENE...] --export DIR
    LP_NUM_THREADS=2 python3 tools/llvmpipe/bench.py DIR [--frames 10] [--samples 4] [--json]

Needs Mesa's EGL and llvmpipe and `pip install PyOpenGL numpy` (see coverage.py). Each scene is
drawn as trirast draws it: 1920x1080 (fill 3840x2160) RGBA8 colour and 32-bit float depth,
LESS, cleared every frame, culling as the scene's JSON says; window scenes (soup, fill) with
smooth colour; the bunny lit per vertex (the same Blinn-Phong head light and clay colour);
the grid with its vertex colours; the dense mesh with one colour per triangle. 3D scenes
write sRGB, as trirast's pipeline does. A frame is timed from the clear to `glFinish`, the
geometry already in GPU buffers (uploaded once, as trirast's timings exclude loading)."""

import argparse
import json
import os
import time

from gl import GL, Framebuffer, attribute, context, program  # noqa: I001  (gl checks imports)
import numpy as np

HEADER = "#version 450\n"
WINDOW_VERTEX = HEADER + """
layout(location = 0) in vec3 window;  // pixels, y down, and depth
layout(location = 1) in vec4 color;
uniform vec2 size;
out vec4 v_color;
void main() {
    gl_Position = vec4(window.xy * (2.0 / size) - 1.0, window.z, 1.0);
    v_color = color;
}
"""
LIT_VERTEX = HEADER + """
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
uniform vec3 origin;
uniform mat4 view;
uniform mat4 view_proj;
uniform mat3 normal_matrix;
uniform vec4 albedo;
uniform vec3 light_direction;  // unit, view space
uniform vec4 light;  // diffuse, ambient, specular, shininess
out vec4 v_color;
void main() {
    vec4 p = vec4(position - origin, 1.0);
    vec3 view_pos = (view * p).xyz;
    vec3 n = normalize(normal_matrix * normal);
    vec3 to_eye = normalize(-view_pos);
    float d = light.x * max(dot(n, light_direction), 0.0) + light.y;  // as Light::shade_towards
    float n_l = dot(n, light_direction);
    float s = n_l > 0.0
        ? light.z * pow(max(dot(n, normalize(light_direction + to_eye)), 0.0), light.w)
        : 0.0;
    v_color = vec4(albedo.rgb * d + s, albedo.a);
    gl_Position = view_proj * p;
}
"""
GRID_VERTEX = HEADER + """
layout(location = 0) in vec4 position;
layout(location = 1) in vec3 color;
out vec4 v_color;
void main() {
    gl_Position = position;
    v_color = vec4(color, 1.0);
}
"""
DENSE_VERTEX = HEADER + """
layout(location = 0) in vec3 position;
uniform mat4 view_proj;
void main() { gl_Position = view_proj * vec4(position, 1.0); }
"""
COLOR_FRAGMENT = HEADER + """
in vec4 v_color;
out vec4 color;
void main() { color = v_color; }
"""
DENSE_FRAGMENT = HEADER + """
out vec4 color;
void main() {
    uint h = uint(gl_PrimitiveID) * 0x9E3779B9u;
    color = vec4(uvec3(h, h >> 8, h >> 16) & 0xFFu, 255.0) / 255.0;
}
"""


def load_scene(directory, name):
    """Uploads a scene; returns (description, draw function, GL buffers)."""
    try:
        with open(os.path.join(directory, f"{name}.json")) as f:
            scene = json.load(f)
    except OSError as e:
        raise SystemExit(f"{e} (was the scene exported?)") from None

    def array(what):
        path = os.path.join(directory, f"{name}_{what}.npy")
        try:
            return np.load(path)
        except OSError as e:
            raise SystemExit(f"{path}: {e} (was the scene exported?)") from None

    vao = GL.glGenVertexArrays(1)
    GL.glBindVertexArray(vao)
    buffers = []
    kind = scene.get("kind")
    if kind not in ("window", "lit", "grid", "dense"):
        raise SystemExit(f"{name}.json: not a scene `trirast bench --export` wrote")
    if kind == "window":
        prog = program(WINDOW_VERTEX, COLOR_FRAGMENT)
        GL.glUseProgram(prog)
        GL.glUniform2f(GL.glGetUniformLocation(prog, "size"), scene["width"], scene["height"])
        positions = array("positions")
        buffers += [attribute(0, positions), attribute(1, array("colors"), normalized=True)]
        count = len(positions)
        indices = None
    else:
        indices = array("indices").astype(np.uint32)
        if kind == "lit":
            prog = program(LIT_VERTEX, COLOR_FRAGMENT)
            GL.glUseProgram(prog)
            buffers += [attribute(0, array("positions")), attribute(1, array("normals"))]
            view = np.array(scene["view"], dtype=np.float32)
            uniform = lambda n: GL.glGetUniformLocation(prog, n)  # noqa: E731
            GL.glUniform3f(uniform("origin"), *scene["origin"])
            GL.glUniformMatrix4fv(uniform("view"), 1, GL.GL_FALSE, view)
            GL.glUniformMatrix4fv(uniform("view_proj"), 1, GL.GL_FALSE,
                                  np.array(scene["view_proj"], dtype=np.float32))
            upper = view.reshape(4, 4)[:3, :3]  # column-major: rows here are columns
            normal_matrix = np.ascontiguousarray(np.linalg.inv(upper).T, dtype=np.float32)
            GL.glUniformMatrix3fv(uniform("normal_matrix"), 1, GL.GL_FALSE, normal_matrix)
            GL.glUniform4f(uniform("albedo"), *scene["albedo"])
            light = scene["light"]
            direction = np.array(light["direction"], dtype=np.float64)
            GL.glUniform3f(uniform("light_direction"), *(direction / np.linalg.norm(direction)))
            GL.glUniform4f(uniform("light"), light["diffuse"], light["ambient"],
                           light["specular"], light["shininess"])
        elif kind == "grid":
            prog = program(GRID_VERTEX, COLOR_FRAGMENT)
            GL.glUseProgram(prog)
            buffers += [attribute(0, array("positions")), attribute(1, array("colors"))]
        elif kind == "dense":
            prog = program(DENSE_VERTEX, DENSE_FRAGMENT)
            GL.glUseProgram(prog)
            GL.glUniformMatrix4fv(GL.glGetUniformLocation(prog, "view_proj"), 1, GL.GL_FALSE,
                                  np.array(scene["view_proj"], dtype=np.float32))
            buffers.append(attribute(0, array("positions")))
        else:
            raise AssertionError(kind)
        element = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, element)
        GL.glBufferData(GL.GL_ELEMENT_ARRAY_BUFFER, indices.nbytes, indices, GL.GL_STATIC_DRAW)
        buffers.append(element)
        count = indices.size
    triangles = count // 3

    # trirast's clip space is D3D's: z in [0, w]; front faces are counter-clockwise in NDC.
    GL.glClipControl(GL.GL_LOWER_LEFT, GL.GL_ZERO_TO_ONE)
    GL.glEnable(GL.GL_DEPTH_TEST)
    GL.glDepthFunc(GL.GL_LESS)
    cull = scene["cull"]
    if cull == "none":
        GL.glDisable(GL.GL_CULL_FACE)
    elif cull in ("back", "front") and kind != "window":
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK if cull == "back" else GL.GL_FRONT)
        GL.glFrontFace(GL.GL_CCW)
    else:
        raise SystemExit(f"{name}: cull {cull!r} is not supported here")
    if kind == "window":
        GL.glDisable(GL.GL_FRAMEBUFFER_SRGB)
    else:
        GL.glEnable(GL.GL_FRAMEBUFFER_SRGB)

    def draw():
        if indices is None:
            GL.glDrawArrays(GL.GL_TRIANGLES, 0, count)
        else:
            GL.glDrawElements(GL.GL_TRIANGLES, count, GL.GL_UNSIGNED_INT, None)

    def release():
        GL.glDeleteBuffers(len(buffers), buffers)
        GL.glDeleteVertexArrays(1, [vao])
        GL.glDeleteProgram(prog)

    return scene, triangles, draw, release


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("directory", help="what `trirast bench --export DIR` wrote")
    parser.add_argument("scenes", nargs="*", help="default: every scene in the directory")
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--samples", type=int, default=1, help="MSAA samples (1 or 4)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.frames < 1:
        parser.error("--frames must be at least 1")
    if not os.path.isdir(args.directory):
        raise SystemExit(f"{args.directory}: no such directory (trirast bench --export DIR)")
    renderer = context()
    scenes = args.scenes or sorted(
        f[:-5] for f in os.listdir(args.directory) if f.endswith(".json")
    )
    if not scenes:
        raise SystemExit(f"{args.directory}: no scenes (trirast bench --export DIR)")
    threads = os.environ.get("LP_NUM_THREADS", "all cores")
    if not args.json:
        print(f"{renderer}, LP_NUM_THREADS={threads}, {args.samples}x")
        print(f"{'scene':<6} {'triangles':>11} {'passed':>12} {'median ms':>10} {'min ms':>10}"
              f" {'Mtri/s':>9}")
    for name in scenes:
        scene, triangles, draw, release = load_scene(args.directory, name)
        target = Framebuffer(
            scene["width"], scene["height"], GL.GL_SRGB8_ALPHA8, depth=True, samples=args.samples
        )
        query = int(np.atleast_1d(GL.glGenQueries(1))[0])
        times = []
        for frame in range(args.frames + 1):
            GL.glFinish()
            start = time.perf_counter()
            GL.glClearColor(0.0, 0.0, 0.0, 1.0)
            GL.glClearDepth(1.0)
            GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
            if frame == 0:
                GL.glBeginQuery(GL.GL_SAMPLES_PASSED, query)
            draw()
            if frame == 0:
                GL.glEndQuery(GL.GL_SAMPLES_PASSED)
            GL.glFinish()
            if frame > 0:  # frame 0 warms up (and compiles llvmpipe's shaders)
                times.append((time.perf_counter() - start) * 1e3)
        passed = GL.glGetQueryObjectuiv(query, GL.GL_QUERY_RESULT)
        GL.glDeleteQueries(1, [query])
        times.sort()
        median, fastest = times[len(times) // 2], times[0]
        rate = triangles / median / 1e3
        if args.json:
            print(json.dumps({"scene": name, "renderer": renderer, "threads": threads,
                              "samples": args.samples,
                              "triangles": triangles, "samples_passed": passed,
                              "median_ms": median, "min_ms": fastest, "mtri_per_s": rate}))
        else:
            print(f"{name:<6} {triangles:>11} {passed:>12} {median:>10.2f} {fastest:>10.2f}"
                  f" {rate:>9.1f}")
        target.delete()
        release()


if __name__ == "__main__":
    main()
