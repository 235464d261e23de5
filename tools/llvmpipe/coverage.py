"""Draws random triangles with trirast and with Mesa's llvmpipe and compares, pixel for pixel
and sample for sample, which triangle each wrote last (triangle ids, no depth test).

    python3 tools/llvmpipe/coverage.py [--trirast target/release/trirast] [--cases 400]
        [--samples 1,4]

Needs Mesa's EGL and llvmpipe (Debian: libegl1 libopengl0 libgl1-mesa-dri) and `pip install
PyOpenGL numpy`. Exits 1 if any case differs (saving its triangles as llvmpipe_SxcaseN.npy in
the temporary directory), 3 if there is no llvmpipe to compare with.

Vertices are on the 1/512 pixel grid, so that half their coordinates fall midway between two
snapped positions (round half to even decides) and many edges pass exactly through pixel
centres or samples (the fill rule decides). They reach llvmpipe exactly: the GL target's sides
are powers of two, so the viewport's scale and offset are exact in f32."""

import argparse
import os
import subprocess
import sys
import tempfile

from gl import GL, Framebuffer, attribute, context, program  # noqa: I001  (gl checks imports)
import numpy as np

DRAW_VERTEX = """#version 450
layout(location = 0) in vec2 window;  // pixels, y down
uniform vec2 size;
void main() {
    // Window y = image row, unflipped: llvmpipe's top-left rule takes "top" as the target's
    // first row in memory (window y = 0), so image row r is window row r.
    gl_Position = vec4(window * (2.0 / size) - 1.0, 0.5, 1.0);
}
"""
DRAW_FRAGMENT = """#version 450
out int id;
void main() { id = gl_PrimitiveID; }
"""
# One sample of a multisampled id texture, read out as a single-sampled image.
SAMPLE_VERTEX = """#version 450
void main() {
    vec2 corner = vec2(gl_VertexID & 1, gl_VertexID >> 1) * 4.0 - 1.0;
    gl_Position = vec4(corner, 0.0, 1.0);
}
"""
SAMPLE_FRAGMENT = """#version 450
uniform isampler2DMS ids;
uniform int sample_index;
uniform ivec2 origin;
out int id;
void main() { id = texelFetch(ids, origin + ivec2(gl_FragCoord.xy), sample_index).r; }
"""


def llvmpipe_ids(programs, triangles, width, height, samples):
    """The last triangle covering each pixel centre or sample (-1: none), (H, W, samples).
    `programs` are the drawing and sample-reading ones (`make_programs`)."""
    # GL clips to the viewport (llvmpipe uses no guard band here), and the clipped vertices,
    # rounded to the grid, move the edges a little. So llvmpipe draws on a target four times
    # as wide and high (still powers of two; `random_triangles` stays inside it), and the
    # middle is cut out.
    origin = np.array([width, height]) * 3 // 2
    full = (4 * width, 4 * height)
    target = Framebuffer(*full, GL.GL_R32I, samples=samples)
    GL.glClearBufferiv(GL.GL_COLOR, 0, np.array([-1, 0, 0, 0], dtype=np.int32))
    draw, read = programs
    GL.glUseProgram(draw)
    GL.glUniform2f(GL.glGetUniformLocation(draw, "size"), *full)
    vao = GL.glGenVertexArrays(1)
    GL.glBindVertexArray(vao)
    data = (np.asarray(triangles) + origin).astype(np.float32).reshape(-1, 2)
    vbo = attribute(0, data)
    GL.glDisable(GL.GL_DEPTH_TEST)
    GL.glDisable(GL.GL_CULL_FACE)
    GL.glDrawArrays(GL.GL_TRIANGLES, 0, len(data))
    out = np.empty((samples, height, width), dtype=np.int32)
    if samples == 1:
        GL.glReadPixels(*origin, width, height, GL.GL_RED_INTEGER, GL.GL_INT, out[0])
    else:
        single = Framebuffer(width, height, GL.GL_R32I)
        GL.glUseProgram(read)
        GL.glBindTexture(GL.GL_TEXTURE_2D_MULTISAMPLE, target.texture)
        GL.glUniform2i(GL.glGetUniformLocation(read, "origin"), *origin)
        for s in range(samples):
            GL.glUniform1i(GL.glGetUniformLocation(read, "sample_index"), s)
            GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
            GL.glReadPixels(0, 0, width, height, GL.GL_RED_INTEGER, GL.GL_INT, out[s])
        single.delete()
    GL.glDeleteBuffers(1, [vbo])
    GL.glDeleteVertexArrays(1, [vao])
    target.delete()
    return out.transpose(1, 2, 0)


def make_programs():
    """The programs `llvmpipe_ids` draws and reads samples with, compiled once."""
    return program(DRAW_VERTEX, DRAW_FRAGMENT), program(SAMPLE_VERTEX, SAMPLE_FRAGMENT)


# trirast's sample patterns (src/sample.rs: the D3D standard ones), 1/16 pixel, y down.
TRIRAST_PATTERNS = {
    4: [(-2, -6), (6, -2), (-6, 2), (2, 6)],
    8: [(1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)],
}


def sample_positions(samples):
    """llvmpipe's sample positions in 1/16 pixel from the pixel centre (x right, y down)."""
    target = Framebuffer(8, 8, GL.GL_R32I, samples=samples)
    positions = []
    for s in range(samples):
        x, y = GL.glGetMultisamplefv(GL.GL_SAMPLE_POSITION, s)
        positions.append((round((x - 0.5) * 16), round((y - 0.5) * 16)))
    target.delete()
    return positions


def trirast_ids(exe, triangles, width, height, samples, workdir):
    """The same with `trirast render --projection window --depth-test always --ids`."""
    obj = os.path.join(workdir, "case.obj")
    with open(obj, "w") as f:
        for tri in triangles:
            for x, y in tri:
                f.write(f"v {float(x)!r} {float(y)!r} 0.5\n")
        for i in range(len(triangles)):
            f.write(f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}\n")
    ids = os.path.join(workdir, "ids.npy")
    cmd = [exe, "render", obj, "--projection", "window", "--size", f"{width}x{height}",
           "--msaa", str(samples), "--per-sample", "--depth-test", "always", "--ids", ids,
           "-o", os.path.join(workdir, "colour.png")]
    try:
        subprocess.run(cmd, check=True, capture_output=True)
    except FileNotFoundError:
        raise SystemExit(f"{exe}: not found (cargo build --release, or pass --trirast)") from None
    except subprocess.CalledProcessError as e:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{e.stderr.decode()}") from None
    ids = np.load(ids)
    return ids.reshape(height, width, samples)


def random_triangles(rng, count, width, height, spread):
    """`count` triangles on the 1/512 grid, within the margin of `llvmpipe_ids`."""
    centre = rng.uniform([-8, -8], [width + 8, height + 8], size=(count, 1, 2))
    offsets = rng.normal(0.0, spread, size=(count, 3, 2))
    inside = np.clip(centre + offsets, [-width, -height], [2 * width, 2 * height])
    return np.round(inside * 512) / 512


def grid_tiling(rng, width, height, step):
    """A jittered grid of quads, each cut along a random diagonal, in random order: a tiling of
    its region, a third of whose points lie exactly on pixel centres."""
    xs = np.arange(-step, width + 2 * step, step, dtype=np.float64)
    ys = np.arange(-step, height + 2 * step, step, dtype=np.float64)
    px, py = np.meshgrid(xs, ys)
    points = np.stack([px, py], axis=-1)
    points += rng.integers(-step * 128, step * 128, size=points.shape) / 512
    on_centre = rng.random(px.shape) < 0.3
    points[on_centre] = np.floor(points[on_centre]) + 0.5
    triangles = []
    for j in range(len(ys) - 1):
        for i in range(len(xs) - 1):
            a, b, c, d = points[j, i], points[j, i + 1], points[j + 1, i + 1], points[j + 1, i]
            if rng.random() < 0.5:
                triangles += [(a, b, c), (a, c, d)]
            else:
                triangles += [(a, b, d), (b, c, d)]
    triangles = np.array(triangles)
    return triangles[rng.permutation(len(triangles))]


def rectangles(rng, width, height):
    """Rectangles with corners on pixel centres, each cut along a diagonal: every edge runs
    along a row or column of centres (or through them), so the fill rule decides them all."""
    corners = np.floor(rng.uniform([-4, -4], [width + 4, height + 4], size=(30, 2, 2))) + 0.5
    triangles = []
    for (x0, y0), (x1, y1) in corners:
        a, b, c, d = (x0, y0), (x1, y0), (x1, y1), (x0, y1)
        triangles += [(a, b, c), (a, c, d)] if rng.random() < 0.5 else [(a, b, d), (b, c, d)]
    return np.array(triangles)


def case_triangles(rng, case, width, height):
    """Small, large, half-pixel-grid, tiling and rectangle cases in turn."""
    kind = case % 5
    if kind == 0:
        return random_triangles(rng, 200, width, height, spread=4.0)
    if kind == 1:
        return random_triangles(rng, 40, width, height, spread=60.0)
    if kind == 2:
        # Vertices on pixel corners and centres: edges through centres, horizontal and
        # vertical edges on them, where only the fill rule decides.
        return np.round(random_triangles(rng, 60, width, height, spread=3.0) * 2) / 2
    if kind == 3:
        return grid_tiling(rng, width, height, step=int(rng.integers(3, 17)))
    return rectangles(rng, width, height)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trirast", default="target/release/trirast")
    parser.add_argument("--cases", type=int, default=400, help="per sample count")
    parser.add_argument("--samples", default="1,4", help="sample counts to compare (1, 4, 8)")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    try:
        counts = [int(n) for n in args.samples.split(",")]
    except ValueError:
        counts = []
    if not counts or any(n not in (1, *TRIRAST_PATTERNS) for n in counts):
        parser.error("--samples takes a comma-separated list of 1, 4 and 8")
    print(context())
    programs = make_programs()
    rng = np.random.default_rng(args.seed)
    width, height = 256, 128
    failed = 0
    with tempfile.TemporaryDirectory() as workdir:
        for samples in counts:
            most = GL.glGetIntegerv(GL.GL_MAX_INTEGER_SAMPLES)
            if samples > most:
                print(f"{samples}x: skipped, this llvmpipe has at most {most} integer samples")
                continue
            if samples > 1:
                positions = sample_positions(samples)
                print(f"{samples}x sample positions (1/16 px):", positions)
                if positions != TRIRAST_PATTERNS[samples]:
                    print(f"{samples}x: llvmpipe samples elsewhere than trirast "
                          f"{TRIRAST_PATTERNS[samples]}: not comparable")
                    failed += 1
                    continue
            mismatched = 0
            for case in range(args.cases):
                triangles = case_triangles(rng, case, width, height)
                ours = trirast_ids(args.trirast, triangles, width, height, samples, workdir)
                theirs = llvmpipe_ids(programs, triangles, width, height, samples)
                differ = np.argwhere(ours != theirs)
                if len(differ):
                    mismatched += 1
                    y, x, s = differ[0]
                    print(f"{samples}x case {case}: {len(differ)} samples differ, first pixel "
                          f"({x}, {y}) sample {s}: trirast {ours[y, x, s]}, "
                          f"llvmpipe {theirs[y, x, s]}")
                    name = f"llvmpipe_{samples}xcase{case}.npy"
                    path = os.path.join(tempfile.gettempdir(), name)
                    np.save(path, triangles)
                    print(f"  triangles saved to {path}")
            print(f"{samples}x: {args.cases - mismatched} of {args.cases} cases identical")
            failed += mismatched
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
