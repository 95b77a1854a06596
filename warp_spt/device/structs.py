"""The structs every kernel reads, and the feature set kernels are specialised to.

One small Warp struct per concept (:class:`Geometry`, :class:`Textures`, ``Materials`` from the
material schema) and :class:`Features`. This is the low half of the device scene: kernels, material
kinds, lights and integrators import these; ``warp_spt.upload.device_scene`` (the high half) uploads a
host scene into them and decides its Features from what the material, light and medium kinds declare.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import warp as wp

from warp_spt.device.lobes import LOBE_ALL, LOBE_SMOOTH
from warp_spt.device.material_table import Materials  # noqa: F401 (kernels import Materials from here)
from warp_spt.device.media_table import Media
from warp_spt.device.layout import WIDTH
from warp_spt.device.proctex import ProcParams
from warp_spt.scene.material_schema import MATERIAL_KINDS

# One wide BVH node's child slots, one lane per child (accel.ray_queries tests a node's boxes at once).
vec_wide_f = wp.types.vector(length=WIDTH, dtype=wp.float32)
vec_wide_i = wp.types.vector(length=WIDTH, dtype=wp.int32)
# Traversal stack lengths a kernel may be compiled with (Features.bvh_stack): the least one that holds
# every mesh's WideBvh.stack_bound. A short stack is faster to set up (it is zeroed per query), and
# three sizes keep the number of kernel variants small.
BVH_STACKS = (16, 64, 512)
@wp.struct
class Geometry:
    """What intersection and surface lookup read: meshes, spheres, the top-level BVH, per-face data."""

    # Triangles: one wp.Mesh per OBJ file (surface points, light sampling); per-face data is
    # concatenated across meshes.
    mesh_ids: wp.array(dtype=wp.uint64)
    # Each mesh's wide BVH (accel.wide_bvh), concatenated: node i's boxes are rows 6i..6i+5 of
    # bvh_box (lower x, y, z, upper x, y, z; one lane per child), its children bvh_child[i]; leaves
    # index the triangles' leaf-ordered corners tri_v0..2 and their face numbers within the mesh.
    bvh_box: wp.array(dtype=vec_wide_f)
    bvh_child: wp.array(dtype=vec_wide_i)
    mesh_root: wp.array(dtype=wp.int32)        # root node of mesh i; -1: the mesh uses Warp's BVH
    tri_v0: wp.array(dtype=wp.vec3)
    tri_v1: wp.array(dtype=wp.vec3)
    tri_v2: wp.array(dtype=wp.vec3)
    tri_face: wp.array(dtype=wp.int32)
    face_offset: wp.array(dtype=wp.int32)      # first face of mesh i in the per-face arrays
    face_material: wp.array(dtype=wp.int32)
    corner_uv: wp.array(dtype=wp.vec2)         # 3 per face
    corner_normal: wp.array(dtype=wp.vec3)     # 3 per face (smooth shading only)
    # 1 when corner_normal holds 3 normals per face. A kernel compiled with smooth-shading code
    # (e.g. Features.general()) for a scene without vn must not read the one-element dummy array:
    # it did, out of bounds, and shaded with garbage normals.
    has_corner_normals: int
    # 3 per face when has_corner_tangents: the uv's u direction at each corner (xyz) and the sign of
    # the bitangent (w), from MikkTSpace-style per-vertex accumulation (upload.tangents); the shading
    # frame of normal maps and anisotropy (Features.needs("frame.uv")).
    corner_tangent: wp.array(dtype=wp.vec4)
    has_corner_tangents: int
    num_meshes: int
    # 3 per face when has_corner_points (the differentiable kernels, asked for a mesh's positions or
    # pose: diff.gradients): the corners in the mesh's own space, read in place of the wp.Mesh's
    # points, whose look-up has no adjoint in Warp 1.19 (mesh_get_point: "MISSINGADJOINT")
    corner_point: wp.array(dtype=wp.vec3)
    has_corner_points: int
    # Analytic spheres
    spheres: wp.array(dtype=wp.vec4)           # centre xyz, radius
    sphere_material: wp.array(dtype=wp.int32)
    # Top-level BVH over mesh bounds (items 0..num_meshes-1, or the instances') and spheres (the rest)
    node_lower: wp.array(dtype=wp.vec3)
    node_upper: wp.array(dtype=wp.vec3)
    node_left: wp.array(dtype=wp.int32)
    node_right: wp.array(dtype=wp.int32)
    node_first: wp.array(dtype=wp.int32)
    node_count: wp.array(dtype=wp.int32)
    items: wp.array(dtype=wp.int32)
    # Instances (read by kernels compiled with Features.instances; a scene without them has one
    # identity placement per mesh, num_instances == num_meshes): top-level item i < num_instances
    # places mesh inst_mesh[i] by the affine map p -> inst_linear[i] p + inst_offset[i] (identity for
    # a mesh in world space); rays go into object space by inst_to_object / inst_to_object_offset,
    # normals come back by inst_normal = A^-T.
    num_instances: int
    inst_mesh: wp.array(dtype=wp.int32)
    inst_linear: wp.array(dtype=wp.mat33)
    inst_offset: wp.array(dtype=wp.vec3)
    inst_to_object: wp.array(dtype=wp.mat33)
    inst_to_object_offset: wp.array(dtype=wp.vec3)
    inst_normal: wp.array(dtype=wp.mat33)
    # Length scale of the scene: ray-origin offsets scale with it (and with |p|)
    extent: float
    # participating media (media): read only by kernels compiled with Features.media
    media: Media


@wp.struct
class Textures:
    """The texture atlas (flat), its tile table (offset, w, h, stride) and the filter (0 nearest, 1 bilinear)."""

    texels: wp.array(dtype=wp.vec3)
    tiles: wp.array(dtype=wp.vec4i)
    bilinear: int
    # procedural instances (warp_spt.device.proctex): kind = index into Features.procedural, parameters
    proc_kind: wp.array(dtype=wp.int32)
    proc_params: wp.array(dtype=ProcParams)


@dataclass(frozen=True)
class Features:
    """What a scene uses; each False lets the kernel drop that code entirely (wp.static).

    The materials' part is what their kinds declare (``warp_spt.bsdfs``, each kind's
    ``declare``): ``lobes``, the union of the lobe flags (``device.lobes``: diffuse / glossy / specular
    x reflection / transmission) the scene's materials can produce, from which integrators decide
    light sampling, MIS and guiding; and ``material_flags``, the names of the code paths the kinds
    need (``"seed.refraction"``, ``"pbr.transmission"``, ``"dims.lobe"``, ``"frame.uv"``, ...: see
    :meth:`needs`). A scene of the seed's kind alone compiles the lean kernel it always compiled.
    The lights' and media's parts are what their kinds declare in the same way (``lights``, ``media``:
    :meth:`lit`, :attr:`samples_lights`); the rest are the geometry's flags.
    """

    meshes: bool = True
    spheres: bool = True
    textures: bool = True
    checker: bool = True
    emitters: bool = True      # some used material emits (its emission is added where a ray hits it)
    smooth: bool = True
    # procedural textures used: sorted (name, source hash); () compiles no procedural code
    procedural: tuple[tuple[str, str], ...] = ()
    # material kinds used (warp_spt.bsdfs), in MATERIAL_KINDS order; one compiles no dispatch
    material_kinds: tuple[str, ...] = MATERIAL_KINDS
    # the union of the used materials' lobes (device.lobes.LOBE_*), and the code paths their kinds need
    lobes: int = LOBE_ALL
    material_flags: tuple[str, ...] = ("*",)     # "*": every code path of every kind (general())
    # entries of the wide BVHs' traversal stack (one of BVH_STACKS, enough for every mesh's tree; 0: no
    # mesh has a wide BVH), and whether some mesh keeps Warp's BVH (WIDE_BVH_MAX_TRIANGLES)
    bvh_stack: int = BVH_STACKS[-1]
    warp_meshes: bool = True
    # the light kinds' declarations (``emitters.LightKind.declare``/``declare_sky``), sorted: a kind's
    # name where it is in the light table (its sampling code is compiled in), "KIND.PATH" for a code
    # path it needs ("triangle.tree", "environment.seen"); "*": every kind and path (general())
    lights: tuple[str, ...] = ("*",)
    # the medium kinds' declarations (``media.registry.declare``), sorted: the kinds used, "emission"
    # where one emits, "interface" behind pass-through boundaries; () compiles no media code
    media: tuple[str, ...] = ()
    # some mesh is placed by transforms (MeshData.transforms): the traversal moves rays into object
    # space and the surface look-up moves points, normals and tangents back (Geometry's inst_* arrays)
    instances: bool = True

    @staticmethod
    def general() -> "Features":
        """The kernel that handles any scene (used to check specialisations against)."""
        return Features()

    def needs(self, flag: str) -> bool:
        """A material kind of the scene asked for this code path (``material_flags``). The flags
        every integrator reads: ``"dims.lobe"`` and ``"dims.fresnel"`` (the bounce's lobe-choice and
        Fresnel-choice random numbers are drawn), ``"frame"`` (the surface carries a shading frame),
        ``"frame.uv"`` (that frame follows the mesh's uv: normal maps, anisotropy), ``"cutout"``
        (some surface has holes: rays pass through where its opacity is below the cut-off)."""
        return flag in self.material_flags or "*" in self.material_flags

    @property
    def scatters(self) -> bool:
        """Some material has a lobe with a density (diffuse or glossy): light sampling and MIS apply."""
        return bool(self.lobes & LOBE_SMOOTH)

    def lit(self, flag: str) -> bool:
        """A light kind declared this name (``lights``): the kind is in the light table, or it needs
        this code path."""
        return flag in self.lights or "*" in self.lights

    @property
    def samples_lights(self) -> bool:
        """Some light can be sampled: a kind declared itself in the light table (a name without a
        path), whichever kind it is."""
        return any("." not in name for name in self.lights)

    def with_lights(self, flags) -> "Features":
        """These features with more light declarations (the sky's, per render)."""
        return replace(self, lights=_union(self.lights, flags))

    def covering(self, scene: "Features") -> "Features":
        """These features with what ``scene`` needs to be rendered right added: its mesh traversal and
        every declared set (``lights``, ``media``) merged, so that a kernel compiled for other features
        (an override) still traces this scene's rays and samples every light of its table."""
        stack = self.bvh_stack if scene.bvh_stack == 0 else max(self.bvh_stack, scene.bvh_stack)
        merged = {name: _union(getattr(self, name), getattr(scene, name)) for name in DECLARED}
        return replace(self, bvh_stack=stack, warp_meshes=self.warp_meshes or scene.warp_meshes,
                       instances=self.instances or scene.instances, **merged)


# the fields of Features that families declare (sets of names, kept sorted so equal sets are equal keys)
DECLARED = ("lights", "media")


def _union(a, b) -> tuple[str, ...]:
    """The sorted union of two declared sets; "*" (everything) absorbs the rest."""
    names = set(a) | set(b)
    return ("*",) if "*" in names else tuple(sorted(names))
