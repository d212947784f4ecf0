"""The pyrender renderer of a :class:`~sim_envs.scenes.scene.Scene` (the maintained fork ``scikit-robot-pyrender``).

Geometry: the scene's meshes and texture coordinates (the same as the MuJoCo backend's). pyrender's cost is mostly
per drawn primitive (Python and PyOpenGL calls), so the colour/depth scene has few, large primitives: one per
repeating texture, one for all stretched textures (posters, book covers, screens...) packed into a texture atlas,
one for all plain colours. Lighting: :meth:`Scene.shade` times the material colour is evaluated per vertex and baked
into vertex colours, and colour is rendered with ``RenderFlags.FLAT`` (texture x vertex colour, no specular, no
gamma): the same Lambertian model MuJoCo evaluates with its lights, and cheaper than pyrender's PBR shading.

Camera: ``IntrinsicsCamera`` with the principal point shifted by +0.5 px, because pyrender (like OpenGL) puts pixel
centres at half-integers while this project's OpenCV convention puts them at integers; node pose
``T_world_cam @ diag(1, -1, -1, 1)`` (OpenGL camera axes). Labels: a second scene with one untextured node per
instance, rendered with ``RenderFlags.SEG`` and one colour per node (instance id + 1 as a 24-bit RGB number).
Multisampling is switched off (pyrender always renders into a 4x multisampled framebuffer; without it labels and depth
at edges come from the pixel centre, as in MuJoCo, and it is faster on a software rasteriser).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError
from sim_envs.render.base import (
    CV_TO_GL,
    DEFAULT_ZNEAR,
    OUTPUTS,
    Renderer,
    RenderOutput,
    validate_outputs,
    validate_pose,
)
from sim_envs.render.gl import configure_gl, context_error
from sim_envs.scenes.scene import Scene, TriMesh


def instance_meshes(scene: Scene) -> dict[int, TriMesh]:
    """World-frame meshes merged per instance id (sorted)."""
    groups: dict[int, list[TriMesh]] = {}
    for prim in scene.primitives:
        groups.setdefault(prim.instance, []).append(prim.mesh())
    return {inst: TriMesh.concatenate(meshes) for inst, meshes in sorted(groups.items())}


ATLAS_WIDTH = 2048  # pixels per row of the texture atlas of stretched (non-repeating) textures (ours)
ATLAS_PAD = 8  # pixels of replicated border around each atlas cell, so mipmaps do not bleed between cells (ours)


def texture_atlas(images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pack (h, w, 3) uint8 images into one atlas (shelf packing, tallest first, padded borders).

    Returns ``(atlas (AH, AW, 3) uint8, scale (n, 2), offset (n, 2))``: an image's texture coordinate (u, v) in
    [0, 1] (v = 0 at its bottom row, OpenGL) maps to ``(u, v) * scale + offset`` in the atlas (v = 0 at its bottom).
    """
    import cv2

    p = ATLAS_PAD
    order = sorted(range(len(images)), key=lambda k: -images[k].shape[0])
    x = y = shelf = 0
    cells: dict[int, tuple[int, int]] = {}
    for k in order:
        h, w = images[k].shape[:2]
        if x + w + 2 * p > ATLAS_WIDTH:
            x, y, shelf = 0, y + shelf, 0
        cells[k] = (x, y)
        x += w + 2 * p
        shelf = max(shelf, h + 2 * p)
    height = y + shelf
    atlas = np.zeros((max(height, 1), ATLAS_WIDTH, 3), np.uint8)
    scale = np.zeros((len(images), 2))
    offset = np.zeros((len(images), 2))
    for k, (x, y) in cells.items():
        h, w = images[k].shape[:2]
        atlas[y : y + h + 2 * p, x : x + w + 2 * p] = cv2.copyMakeBorder(images[k], p, p, p, p, cv2.BORDER_REPLICATE)
        scale[k] = (w / ATLAS_WIDTH, h / height)
        offset[k] = ((x + p) / ATLAS_WIDTH, (height - (y + p + h)) / height)
    return atlas, scale, offset


def colour_batches(scene: Scene) -> list[tuple[np.ndarray | None, TriMesh, np.ndarray]]:
    """The colour pass's primitives: ``(texture or None, world mesh, (N, 3) float32 vertex colours)``.

    One batch per repeating texture; one for all stretched textures (posters, covers, screens...) through a texture
    atlas; one for all plain materials. Vertex colours are the material colour times :meth:`Scene.shade`.
    """
    materials = scene.materials()
    stretched = [m for m in materials if m.texture is not None and m.tile_m is None]
    slot = {id(m): k for k, m in enumerate(stretched)}
    atlas, scale, offset = texture_atlas([m.texture for m in stretched]) if stretched else (None, None, None)
    groups: dict[object, tuple[np.ndarray | None, list[TriMesh], list[np.ndarray]]] = {}
    for prim in scene.primitives:
        mat = prim.material
        mesh = prim.mesh()
        colours = (scene.shade(mesh.normals)[:, None] * np.asarray(mat.rgb)[None]).astype(np.float32)
        if mat.texture is None:
            key, texture = "plain", None
        elif mat.tile_m is None:
            key, texture = "atlas", atlas
            k = slot[id(mat)]
            mesh = TriMesh(mesh.vertices, mesh.normals, mesh.uv * scale[k] + offset[k], mesh.faces)
        else:
            key, texture = id(mat), mat.texture
        entry = groups.setdefault(key, (texture, [], []))
        entry[1].append(mesh)
        entry[2].append(colours)
    return [(tex, TriMesh.concatenate(meshes), np.concatenate(cols)) for tex, meshes, cols in groups.values()]


def _node_pose(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pose (4, 4) translating to the vertices' centre, vertices relative to it as float32).

    pyrender draws opaque nodes sorted by the distance of their origin to the camera, in set (memory) order for ties;
    distinct origins make the order, which decides exact depth ties, deterministic.
    """
    centre = vertices.mean(0)
    pose = np.eye(4)
    pose[:3, 3] = centre
    return pose, (vertices - centre).astype(np.float32)


def instance_colour(instance: int) -> tuple[int, int, int]:
    """The segmentation colour of an instance id: ``instance + 1`` as a 24-bit (r, g, b) number (0 = background)."""
    code = instance + 1
    return (code & 255, (code >> 8) & 255, (code >> 16) & 255)


def _single_sample_framebuffer(renderer: Any) -> None:
    """Make pyrender's main framebuffer single-sampled (its 'multisample' renderbuffers get 0 samples).

    pyrender creates the framebuffer on the first render and re-creates it when the viewport changes; this re-specifies
    the storage of its multisample colour and depth renderbuffers with 0 samples right after each creation.
    """
    from OpenGL import GL

    inner = renderer._renderer
    original = inner._configure_main_framebuffer

    def configure() -> None:
        fresh = inner._main_fb is None
        original()
        if fresh:
            w, h = inner.viewport_width, inner.viewport_height
            for buffer, fmt in ((inner._main_cb_ms, GL.GL_RGBA), (inner._main_db_ms, GL.GL_DEPTH_COMPONENT24)):
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, buffer)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, 0, fmt, w, h)

    inner._configure_main_framebuffer = configure


def _keep_egl_display(renderer: Any) -> None:
    """Make pyrender's EGL platform destroy only its own context when deleted.

    pyrender calls ``eglTerminate`` on the display when a renderer is deleted, but an EGL display is shared by every
    context of the process (other pyrender renderers, MuJoCo's): terminating it breaks them all. The display stays
    initialised until the process exits.
    """
    platform = renderer._platform
    if not hasattr(platform, "_egl_display"):
        return  # OSMesa: contexts are independent

    def delete_context() -> None:
        from OpenGL import EGL

        if platform._egl_display is not None and platform._egl_context is not None:
            try:
                EGL.eglMakeCurrent(platform._egl_display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
                EGL.eglDestroyContext(platform._egl_display, platform._egl_context)
            except EGL.EGLError:  # the display was terminated (MuJoCo does so at exit): its contexts are gone
                pass
        platform._egl_context = None
        platform._egl_display = None

    platform.delete_context = delete_context


def build_scene(scene: Scene, intrinsics: Intrinsics, znear: float, zfar: float) -> dict[str, Any]:
    """The pyrender scene of ``scene``: returns ``{"scene", "camera_node", "colour_meshes", "seg_meshes", "seg_map"}``.

    One pyrender scene holds two sets of nodes (pyrender re-uploads every buffer when it switches scenes): colour
    nodes, one per :func:`colour_batches` batch (textured, lighting baked into vertex colours) for colour and depth,
    and label nodes, one untextured node per instance for ``RenderFlags.SEG`` with ``seg_map`` (node -> colour).
    The label meshes are hidden during colour and depth passes; the SEG pass draws only the nodes of ``seg_map``.
    """
    import pyrender

    sampler = pyrender.Sampler(
        magFilter=pyrender.constants.GLTF.LINEAR,
        minFilter=pyrender.constants.GLTF.LINEAR_MIPMAP_LINEAR,
        wrapS=pyrender.constants.GLTF.REPEAT,
        wrapT=pyrender.constants.GLTF.REPEAT,
    )
    camera = pyrender.IntrinsicsCamera(
        fx=intrinsics.fx, fy=intrinsics.fy, cx=intrinsics.cx + 0.5, cy=intrinsics.cy + 0.5, znear=znear, zfar=zfar
    )
    prs = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 1.0), ambient_light=(0.0, 0.0, 0.0))
    colour_meshes = []
    for g, (image, mesh, rgb) in enumerate(colour_batches(scene)):
        texture = None
        if image is not None:
            texture = pyrender.Texture(source=image, source_channels="RGB", sampler=sampler)
        material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(1.0, 1.0, 1.0, 1.0), baseColorTexture=texture, metallicFactor=0.0, roughnessFactor=1.0
        )
        colours = np.concatenate([rgb, np.ones((len(rgb), 1), np.float32)], 1)
        pose, positions = _node_pose(mesh.vertices)
        primitive = pyrender.Primitive(
            positions=positions,
            normals=mesh.normals.astype(np.float32),
            texcoord_0=mesh.uv.astype(np.float32) if texture is not None else None,
            color_0=colours,
            indices=mesh.faces.astype(np.uint32),
            material=material,
        )
        colour_meshes.append(pyrender.Mesh(primitives=[primitive]))
        prs.add(colour_meshes[-1], name=f"batch_{g}", pose=pose)
    seg_map = {}
    seg_meshes = []
    for inst, mesh in instance_meshes(scene).items():
        pose, positions = _node_pose(mesh.vertices)
        seg_meshes.append(
            pyrender.Mesh(primitives=[pyrender.Primitive(positions=positions, indices=mesh.faces.astype(np.uint32))])
        )
        node = prs.add(seg_meshes[-1], name=f"instance_{inst}", pose=pose)
        seg_map[node] = instance_colour(inst)
    return {
        "scene": prs, "camera_node": prs.add(camera, pose=np.eye(4)), "colour_meshes": colour_meshes,
        "seg_meshes": seg_meshes, "seg_map": seg_map,
    }  # fmt: skip


class PyrenderRenderer(Renderer):
    """Renders a :class:`Scene` with pyrender (see the module docstring). ``znear`` in metres."""

    backend = "pyrender"

    def __init__(self, scene: Scene, intrinsics: Intrinsics, znear: float = DEFAULT_ZNEAR) -> None:
        if scene.lighting != "flat":
            raise SimEnvError(
                f"the pyrender renderer draws flat-lit scenes only (lighting baked into vertex colours); this scene's "
                f"lighting is {scene.lighting!r}: render it with renderer='mujoco' (lamps, shadows, highlights)"
            )
        super().__init__(scene, intrinsics, znear)

    def _ensure_context(self) -> dict[str, Any]:
        """Create the pyrender scene and the offscreen OpenGL context on first use."""
        if self._gl is not None:
            return self._gl
        platform = configure_gl()
        try:
            import pyrender

            built = build_scene(self.scene, self.intrinsics, self.znear, self.zfar)
            offscreen = pyrender.OffscreenRenderer(self.intrinsics.width, self.intrinsics.height)
        except Exception as exc:  # noqa: BLE001 - any failure here means no usable OpenGL
            raise context_error("pyrender renderer", platform, exc) from exc
        _single_sample_framebuffer(offscreen)
        _keep_egl_display(offscreen)
        self._gl = {"pyrender": pyrender, "offscreen": offscreen, **built}
        self._track()
        return self._gl

    def render(self, T_world_cam: np.ndarray, outputs: Iterable[str] = OUTPUTS) -> RenderOutput:
        """Render the view from ``T_world_cam`` ((4, 4) camera-to-world, OpenCV axes); only ``outputs`` are computed."""
        wanted = validate_outputs(outputs)
        T = validate_pose(T_world_cam).copy()
        gl = self._ensure_context()
        flags = gl["pyrender"].RenderFlags
        T[:3, :3] = T[:3, :3] @ CV_TO_GL
        rgb = depth = instances = None
        gl["scene"].set_pose(gl["camera_node"], T)
        if wanted & {"rgb", "depth"}:
            # colour and depth come from the same nodes whatever else is asked for, so depth is the same bytes
            self._show_labels(False)
            if "rgb" in wanted:
                rgb, depth = gl["offscreen"].render(gl["scene"], flags=flags.FLAT)
            else:
                depth = gl["offscreen"].render(gl["scene"], flags=flags.DEPTH_ONLY)
        if wanted & {"labels", "instances"}:
            self._show_labels(True)  # the SEG pass draws only the nodes of seg_map: the label nodes
            seg, _ = gl["offscreen"].render(gl["scene"], flags=flags.SEG, seg_node_map=gl["seg_map"])
            code = (
                seg[..., 0].astype(np.int32)
                | (seg[..., 1].astype(np.int32) << 8)
                | (seg[..., 2].astype(np.int32) << 16)
            )
            instances = code - 1
        return RenderOutput(
            rgb=np.ascontiguousarray(rgb) if rgb is not None else None,
            depth=np.ascontiguousarray(depth, dtype=np.float32) if "depth" in wanted else None,
            labels=self.labels_of(instances) if "labels" in wanted else None,
            instances=instances.astype(np.int32) if "instances" in wanted else None,
        )

    def _show_labels(self, on: bool) -> None:
        """Show the label meshes (and hide the colour meshes) or the reverse."""
        for mesh in self._gl["seg_meshes"]:
            mesh.is_visible = on
        for mesh in self._gl["colour_meshes"]:
            mesh.is_visible = not on

    def close(self) -> None:
        """Delete the OpenGL context (a later render creates it again)."""
        gl, self._gl = self._gl, None
        if gl is not None:
            gl["offscreen"].delete()
