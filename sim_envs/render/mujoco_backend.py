"""The MuJoCo renderer: a model built in code with ``mujoco.MjSpec`` from a :class:`~sim_envs.scenes.scene.Scene`.

Geometry: one mesh geom per (instance, material) pair, in world coordinates, with the scene's own texture coordinates
and flat/smooth normals (:meth:`Primitive.mesh`), so texture mapping is identical to the pyrender backend's.
Textures come from numpy arrays. Lighting reproduces :meth:`Scene.shade`: the headlight gives only the ambient term,
and each scene light is a MuJoCo directional light with diffuse colour = intensity (no specular, no shadows). A
``lit`` scene (:mod:`sim_envs.scenes.lighting`) adds its lamps as MuJoCo spot lights (attenuation, cone, shadow maps of
1024 x 1024 for those that cast shadows) and its materials' specular, shininess and emission.

Camera: the model's one camera gets exact pinhole intrinsics through ``cam_intrinsic`` / ``cam_sensorsize`` and is
posed per frame by writing ``data.cam_xpos`` / ``data.cam_xmat`` (MuJoCo cameras look down -z with y up:
``R_mujoco = R_opencv @ diag(1, -1, -1)``).

Passes (each ``mjr_render``, only those needed): RGB (colour and, when asked, the depth buffer) and segmentation
(``mjRND_SEGMENT | mjRND_IDCOLOR``: geom ids -> instance -> class, and the depth buffer when RGB was not asked for).
Depth is read from MuJoCo's reversed-z float depth buffer and converted to planar z in metres; background -> 0.
Costs cut as the stack notes measured: no shadows (unless a lit scene's lamps cast them), reflections or skybox,
``offsamples = 0``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from sim_envs.camera import Intrinsics
from sim_envs.frames import NO_DEPTH
from sim_envs.render.base import (
    CV_TO_GL,
    OUTPUTS,
    Renderer,
    RenderOutput,
    validate_outputs,
    validate_pose,
)
from sim_envs.render.gl import configure_gl, context_error
from sim_envs.scenes.scene import Material, Scene, TriMesh

SHADOW_MAP_SIZE = 1024  # texels per side of a shadow map (ours: at 320x240 as sharp as 2048, 2.4x faster)
LIT_MAX_EDGE_M = 0.5  # a lit scene's meshes are split down to this edge length (MuJoCo lights per vertex; ours)
LAMP_SPECULAR = 0.5  # a lamp's specular colour per unit of its diffuse intensity (ours)


def _merged_meshes(scene: Scene) -> list[tuple[int, Material, TriMesh]]:
    """World-frame meshes of ``scene`` merged per (instance, material), in order of first appearance; a lit scene's
    split into triangles of edges <= :data:`LIT_MAX_EDGE_M` (:meth:`TriMesh.subdivided`: MuJoCo lights per vertex)."""
    groups: dict[tuple[int, int], tuple[int, Material, list[TriMesh]]] = {}
    for prim in scene.primitives:
        key = (prim.instance, id(prim.material))
        mesh = prim.mesh() if scene.lighting == "flat" else prim.mesh().subdivided(LIT_MAX_EDGE_M)
        groups.setdefault(key, (prim.instance, prim.material, []))[2].append(mesh)
    return [(inst, mat, TriMesh.concatenate(meshes)) for inst, mat, meshes in groups.values()]


def build_model(scene: Scene, intrinsics: Intrinsics, znear: float, zfar: float) -> tuple[Any, np.ndarray]:
    """Compile the MuJoCo model of ``scene`` with one camera of ``intrinsics``.

    Returns ``(model, geom_instance)``: the ``mujoco.MjModel`` and (ngeom,) int32 instance id of each geom.
    ``znear`` / ``zfar`` are metres (MuJoCo stores them relative to ``stat.extent``, which is set here).
    """
    import mujoco

    spec = mujoco.MjSpec()
    spec.modelname = f"{scene.style}_{scene.seed}"
    spec.compiler.degree = False
    vis = spec.visual
    vis.global_.offwidth, vis.global_.offheight = intrinsics.width, intrinsics.height
    vis.quality.offsamples = 0  # no multisampling: labels and depth stay exact at edges, and it is faster
    vis.quality.shadowsize = SHADOW_MAP_SIZE if any(lamp.shadows for lamp in scene.lamps) else 0
    vis.headlight.active = 1
    vis.headlight.ambient = [scene.ambient] * 3  # the ambient term of Scene.shade
    vis.headlight.diffuse = [0.0] * 3
    vis.headlight.specular = [0.0] * 3
    vis.rgba.haze = [0.0, 0.0, 0.0, 1.0]
    extent = zfar
    spec.stat.extent = extent
    spec.stat.center = list(np.asarray(scene.room_size, dtype=float) / 2)
    vis.map.znear = znear / extent
    vis.map.zfar = 1.0  # zfar metres = vis.map.zfar * extent

    for light in scene.lights:
        spec.worldbody.add_light(
            type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
            dir=list(light.direction),
            diffuse=[light.intensity] * 3,
            ambient=[0.0] * 3,
            specular=[0.0] * 3,
            castshadow=False,
            pos=list(np.asarray(scene.room_size, dtype=float) / 2),
        )

    for lamp in scene.lamps:
        spec.worldbody.add_light(
            type=mujoco.mjtLightType.mjLIGHT_SPOT,
            pos=list(lamp.position),
            dir=list(lamp.direction),
            cutoff=lamp.cutoff_deg,  # MuJoCo takes a light's cutoff in degrees whatever compiler.degree says
            exponent=lamp.exponent,
            attenuation=list(lamp.attenuation),
            diffuse=[lamp.intensity] * 3,
            ambient=[0.0] * 3,
            specular=[LAMP_SPECULAR * lamp.intensity] * 3,
            castshadow=lamp.shadows,
        )

    for k, mat in enumerate(scene.materials()):
        material = spec.add_material(name=f"mat{k}")
        material.rgba = [*mat.rgb, 1.0]
        material.specular = mat.specular
        material.shininess = mat.shininess
        material.reflectance = 0.0
        material.emission = mat.emission
        if mat.texture is not None:
            tex = mat.texture
            # MuJoCo's texture row 0 is v = 0; the scene's convention puts v = 0 at the image's bottom row
            spec.add_texture(
                name=f"tex{k}",
                type=mujoco.mjtTexture.mjTEXTURE_2D,
                colorspace=mujoco.mjtColorSpace.mjCOLORSPACE_LINEAR,
                width=tex.shape[1],
                height=tex.shape[0],
                nchannel=3,
            ).data = np.ascontiguousarray(tex[::-1]).tobytes()
            material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"tex{k}"
            material.texrepeat = [1.0, 1.0]
            material.texuniform = False
    mat_index = {id(m): k for k, m in enumerate(scene.materials())}

    geom_instance = []
    for g, (inst, mat, mesh) in enumerate(_merged_meshes(scene)):
        m = spec.add_mesh(name=f"mesh{g}")
        m.uservert = mesh.vertices.astype(np.float32).ravel().tolist()
        m.usernormal = mesh.normals.astype(np.float32).ravel().tolist()
        m.usertexcoord = mesh.uv.astype(np.float32).ravel().tolist()
        m.userface = mesh.faces.ravel().tolist()
        m.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL  # thin or open shapes have no volume
        spec.worldbody.add_geom(
            name=f"geom{g}",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=f"mesh{g}",
            material=f"mat{mat_index[id(mat)]}",
            contype=0,
            conaffinity=0,
            group=0,
        )
        geom_instance.append(inst)
    spec.worldbody.add_camera(name="cam")
    model = spec.compile()
    model.cam_sensorsize[0] = [intrinsics.width, intrinsics.height]
    model.cam_intrinsic[0] = [intrinsics.fx, intrinsics.fy, *_principal_offset(intrinsics)]
    return model, np.asarray(geom_instance, dtype=np.int32)


def _principal_offset(intrinsics: Intrinsics) -> tuple[float, float]:
    """MuJoCo's principal-point terms of ``cam_intrinsic`` for an OpenCV (cx, cy) with pixel centres at integers.

    MuJoCo takes the offsets of the image centre from the principal point, ``(W/2 - cx', H/2 - cy')``, with its pixel
    centres at half-integers (cx' = cx + 0.5): the image centre in OpenCV pixel coordinates is ((W - 1) / 2,
    (H - 1) / 2). Checked to a quarter pixel by the known-answer tests of test_render_intrinsics.py.
    """
    return ((intrinsics.width - 1) / 2 - intrinsics.cx, (intrinsics.height - 1) / 2 - intrinsics.cy)


class MujocoRenderer(Renderer):
    """Renders a :class:`Scene` with MuJoCo (see the module docstring). ``znear`` in metres."""

    backend = "mujoco"

    def _ensure_context(self) -> dict[str, Any]:
        """Create the model, the OpenGL context and MuJoCo's render context on first use."""
        if self._gl is not None:
            return self._gl
        platform = configure_gl()
        import mujoco

        model, geom_instance = build_model(self.scene, self.intrinsics, self.znear, self.zfar)
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)  # light directions (data.light_xdir) for mjv_updateScene
        width, height = self.intrinsics.width, self.intrinsics.height
        try:
            if platform == "egl":
                from mujoco.egl import GLContext
            else:
                from mujoco.osmesa import GLContext
            context = GLContext(width, height)
            context.make_current()
            mjr = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_50)
        except Exception as exc:  # noqa: BLE001 - any failure here means no usable OpenGL
            raise context_error("mujoco renderer", platform, exc) from exc
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, mjr)
        mjr.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR  # reversed z: 0 = far / background
        scn = mujoco.MjvScene(model, maxgeom=model.ngeom + 16)
        off = ("mjRND_SHADOW", "mjRND_REFLECTION", "mjRND_SKYBOX", "mjRND_FOG", "mjRND_HAZE")
        for flag in off:
            scn.flags[getattr(mujoco.mjtRndFlag, flag)] = 0
        scn.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = int(any(lamp.shadows for lamp in self.scene.lamps))
        option = mujoco.MjvOption()
        camera = mujoco.MjvCamera()
        camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        camera.fixedcamid = 0
        mujoco.mjv_updateScene(model, data, option, None, camera, mujoco.mjtCatBit.mjCAT_ALL, scn)
        # segmentation colour (segid + 1, 0 = background) -> instance id + 1 (0 = none)
        lut = np.zeros(scn.ngeom + 2, dtype=np.int32)
        for k in range(scn.ngeom):
            g = scn.geoms[k]
            if g.segid >= 0 and g.objtype == mujoco.mjtObj.mjOBJ_GEOM:
                lut[g.segid + 1] = geom_instance[g.objid] + 1
        self._gl = {
            "mujoco": mujoco, "model": model, "data": data, "context": context, "mjr": mjr, "scene": scn,
            "option": option, "camera": camera, "rect": mujoco.MjrRect(0, 0, width, height), "seg_lut": lut,
        }  # fmt: skip
        self._track()
        return self._gl

    def render(self, T_world_cam: np.ndarray, outputs: Iterable[str] = OUTPUTS) -> RenderOutput:
        """Render the view from ``T_world_cam`` ((4, 4) camera-to-world, OpenCV axes); only ``outputs`` are computed."""
        wanted = validate_outputs(outputs)
        T = validate_pose(T_world_cam)
        gl = self._ensure_context()
        mujoco, model, data, scn = gl["mujoco"], gl["model"], gl["data"], gl["scene"]
        gl["context"].make_current()
        data.cam_xpos[0] = T[:3, 3]
        data.cam_xmat[0] = (T[:3, :3] @ CV_TO_GL).ravel()
        mujoco.mjv_updateScene(model, data, gl["option"], None, gl["camera"], mujoco.mjtCatBit.mjCAT_ALL, scn)
        H, W = self.intrinsics.height, self.intrinsics.width
        want_seg = bool(wanted & {"labels", "instances"})
        rgb = depth_raw = instances = None
        if "rgb" in wanted:
            rgb = np.empty((H, W, 3), np.uint8)
            depth_raw = np.empty((H, W), np.float32) if "depth" in wanted else None
            scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 0
            scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 0
            mujoco.mjr_render(gl["rect"], scn, gl["mjr"])
            mujoco.mjr_readPixels(rgb, depth_raw, gl["rect"], gl["mjr"])
        if want_seg or ("depth" in wanted and depth_raw is None):
            seg = np.empty((H, W, 3), np.uint8)
            need_depth = "depth" in wanted and depth_raw is None
            if need_depth:
                depth_raw = np.empty((H, W), np.float32)
            scn.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = 1
            scn.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = 1
            mujoco.mjr_render(gl["rect"], scn, gl["mjr"])
            mujoco.mjr_readPixels(seg if want_seg else None, depth_raw if need_depth else None, gl["rect"], gl["mjr"])
            if want_seg:
                segid = (
                    seg[..., 0].astype(np.int32)
                    | (seg[..., 1].astype(np.int32) << 8)
                    | (seg[..., 2].astype(np.int32) << 16)
                )
                instances = gl["seg_lut"][np.minimum(segid, len(gl["seg_lut"]) - 1)][::-1] - 1
        depth = self._linear_depth(depth_raw[::-1]) if depth_raw is not None else None
        return RenderOutput(
            rgb=np.ascontiguousarray(rgb[::-1]) if rgb is not None else None,
            depth=depth,
            labels=self.labels_of(instances) if "labels" in wanted else None,
            instances=np.ascontiguousarray(instances) if "instances" in wanted else None,
        )

    def _linear_depth(self, raw: np.ndarray) -> np.ndarray:
        """Reversed-z depth buffer values (H, W) -> planar z (H, W) float32 metres, 0 where nothing was drawn."""
        model = self._gl["model"]
        extent = float(model.stat.extent)
        near = np.float32(model.vis.map.znear * extent)
        far = np.float32(model.vis.map.zfar * extent)
        # the same float32 projection terms as glFrustum, transformed for reversed z (as mujoco.Renderer does)
        c = -(far + near) / (far - near)
        d = -(np.float32(2) * far * near) / (far - near)
        c = np.float64(np.float32(-0.5) * c - np.float32(0.5))
        d = np.float64(np.float32(-0.5) * d)
        raw64 = raw.astype(np.float64)
        with np.errstate(divide="ignore"):
            z = d / (raw64 + c)
        return np.where(raw > 0, z, NO_DEPTH).astype(np.float32)

    def close(self) -> None:
        """Free MuJoCo's render context and the OpenGL context (a later render creates them again)."""
        gl, self._gl = self._gl, None
        if gl is None:
            return
        gl["mjr"].free()
        gl["context"].free()
