"""The view-independent LSAD store: light-chain nodes plus the scene they were traced in.

For a Lambertian scene the nodes of the light chains (position, normal, incident-flux
coefficient, kind, batch) are all a renderer needs: any view is rendered from them by
tracing only its primary rays and the visibility rays to the nodes (the double local
estimate, :func:`lsadphoto.solver.render`). This is the "view independence" of the seed
paper: one simulation serves every observer. For a scene with glossy, specular or
transmitting materials the nodes also hold each chain's incoming direction and the side it
hit (the BSDF at a node depends on both), and the scene its
:class:`~lsadphoto.solver.materials.Material` list.

The file is a NumPy ``.npz`` archive (written atomically: temporary file + rename) with the
node arrays, the triangulated scene and a JSON header (``meta``) holding luminaires,
views, materials and provenance.

References
----------
Budak, V. P., Chembaev, V. D., Meshkova, A. V., Zheltov, V. S. (2020). Luminance
spatial-angular distribution and the quality criterion of lighting. GraphiCon 2020 (§2:
storage of the computed LSAD). Keller, A. (1997). Instant radiosity. *SIGGRAPH '97*.
"""

import json
import math
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import BadInputError, UnsupportedFileError
from ..geometry.base import projection_from_dict
from .._atomic import atomic_path
from .cache_grid import SurfaceCache
from .materials import Material
from .photometry import Photometry
from .scene import AreaLuminaire, PointLuminaire, Scene, View
from .sky import DistantSource

__all__ = ["READABLE_FORMATS", "STORE_FORMAT", "LsadStore", "load_store"]

#: Identifier and version of the store file layout written: /4 adds the nodes' ``incoming``
#: and ``front`` and the scene's ``surface_materials`` (scenes with non-Lambertian materials),
#: /5 the nodes' ``direct`` and the store's ``fresnel_rule``.
STORE_FORMAT = "lsadphoto-lsad-store/5"
#: Layouts :func:`load_store` reads: /3 (Lambertian scenes only) is /4 without those; /4 is /5
#: of the reciprocal rule without ``direct`` (which that rule does not use).
READABLE_FORMATS = ("lsadphoto-lsad-store/3", "lsadphoto-lsad-store/4", STORE_FORMAT)

#: Node kinds: 0 = cosine lobe (Lambertian surface or emitter), 1 = intensity distribution
#: of a point luminaire (index in ``luminaire``).
KIND_COSINE, KIND_POINT = 0, 1

_NODE_FIELDS = ("position", "normal", "coefficient", "kind", "luminaire", "batch", "depth", "triangle")
#: Further node fields of a store of a scene with non-Lambertian materials.
_MATERIAL_FIELDS = ("incoming", "front", "direct")


@dataclass
class LsadStore:
    """Nodes of ``chains`` light chains traced in ``scene``.

    Attributes
    ----------
    scene : Scene
    position, normal : ndarray, shape (k, 3)
        Node position [m] and the unit normal of the side the node was reached from.
    coefficient : ndarray, shape (k,)
        For cosine nodes, W·ρ/π (W·1/π at an emitter) [lm·sr⁻¹] — in a scene with
        non-Lambertian materials (``materials``) the chain's weight W [lm] at surface nodes,
        the BSDF being evaluated at rendering; for point nodes Φ_total/Φ_luminaire [–]. All
        before division by the chains per batch.
    kind, luminaire, batch, depth, triangle : ndarray of int, shape (k,)
        Node kind, point-luminaire index (−1 otherwise), batch index, bounce number
        (0 at the source) and triangle id (−1 for point luminaires).
    incoming : ndarray, shape (k, 3), or None
        Non-Lambertian scenes: the unit direction back along the chain's arriving ray
        (zero at source nodes); None for Lambertian scenes.
    front : ndarray of bool, shape (k,), or None
        Non-Lambertian scenes: whether the node was reached on its triangle's front side.
    direct : ndarray of bool, shape (k,), or None
        Non-Lambertian scenes: at source nodes, whether the luminaire can be a light source of
        Radiance's direct calculation (an area luminaire within its ``light_source_radius``);
        at surface nodes, whether the light arriving there came straight from one (through
        straight-through transmissions only). Used by the ``"radiance"`` rule.
    fresnel_rule : str
        The smooth materials' rule for the factor 1 − F(μ_i) the chains were traced with
        (:data:`~lsadphoto.solver.materials.FRESNEL_RULES`); views rendered from the store
        use it.
    chains : int
        Number of light chains; each of the ``batches`` batches holds ``chains/batches``.
    surface_cache : SurfaceCache or None
        Indirect illuminance on the scene's surfaces
        (:func:`~lsadphoto.solver.integrators.surface_cache.build_surface_cache`), saved with the store.
    node_hull : ndarray, shape (h, 3), or None
        The vertices of the convex hull of the surface nodes' positions (depth ≥ 1) once
        :meth:`surface_node_hull` has computed them (saved with the store, so that a further
        view does not compute them again); None before.
    """

    scene: Scene
    position: np.ndarray
    normal: np.ndarray
    coefficient: np.ndarray
    kind: np.ndarray
    luminaire: np.ndarray
    batch: np.ndarray
    depth: np.ndarray
    triangle: np.ndarray
    chains: int
    batches: int
    seed: int = 0
    near_field: str = "unbiased"
    provenance: dict = field(default_factory=dict)
    surface_cache: object = None
    incoming: np.ndarray = None
    front: np.ndarray = None
    direct: np.ndarray = None
    fresnel_rule: str = "reciprocal"
    node_hull: np.ndarray = None

    def __post_init__(self):
        if (self.incoming is None) != self.scene.lambertian:
            raise BadInputError("a store of a scene with non-Lambertian materials needs the nodes' incoming "
                                "directions and sides (and a Lambertian scene's store none)")

    def __repr__(self):
        return (f"LsadStore({self.scene!r}, {self.chains} chains in {self.batches} batches, "
                f"{self.nodes} nodes, seed {self.seed})")

    @property
    def nodes(self):
        """Number of stored nodes."""
        return len(self.coefficient)

    @property
    def materials(self):
        """Whether the scene has non-Lambertian materials (nodes of BSDF-sampled chains)."""
        return self.incoming is not None

    @property
    def chains_per_batch(self):
        """Light chains in each batch."""
        return self.chains // self.batches

    def surface_node_hull(self):
        """Vertices of the convex hull of the surface nodes' positions [m], shape (h, 3):
        the support function max over them of n·p is the largest n·p over all surface nodes
        (all of them where the set is flat or has at most 4 points). Computed once (Qhull,
        about 0.2 s for 330 000 nodes) and kept."""
        if self.node_hull is None:
            from scipy.spatial import ConvexHull, QhullError

            pos = self.position[self.depth > 0]
            try:
                self.node_hull = pos[ConvexHull(pos).vertices] if len(pos) > 4 else pos
            except (QhullError, ValueError):  # flat or degenerate node sets: all of them
                self.node_hull = pos
        return self.node_hull

    def extend(self, other):
        """Append the nodes and chains of another store of the same scene (in place); a
        surface cache built from the old nodes is dropped."""
        if other.fresnel_rule != self.fresnel_rule:
            raise BadInputError(f"stores of Fresnel rules {self.fresnel_rule!r} and {other.fresnel_rule!r} do not mix")
        for name in _NODE_FIELDS + (_MATERIAL_FIELDS if self.materials else ()):
            setattr(self, name, np.concatenate([getattr(self, name), getattr(other, name)]))
        self.chains += other.chains
        self.surface_cache = None
        self.node_hull = None

    def save(self, path):
        """Write the store to ``path`` (``.npz``) atomically."""
        path = Path(path)
        scene = self.scene
        meta = {
            "format": STORE_FORMAT,
            "version": __version__,
            "chains": int(self.chains),
            "batches": int(self.batches),
            "seed": int(self.seed),
            "near_field": self.near_field,
            "fresnel_rule": self.fresnel_rule,
            "provenance": self.provenance,
            "scene": {
                "name": scene.name,
                "material_names": list(scene.material_names),
                "area_luminaires": [{"name": l.name, "flux": l.flux, "light_source_radius":
                                     None if math.isinf(l.light_source_radius) else l.light_source_radius}
                                    for l in scene.area_luminaires],
                "point_luminaires": [
                    {"name": l.name, "position": l.position.tolist(), "frame": l.frame.tolist(),
                     "extent": list(l.extent), "multiplier": l.multiplier,
                     "photometry": {"source": l.photometry.source, "format": l.photometry.format}}
                    for l in scene.point_luminaires],
                "views": [
                    {"name": v.name, "position": v.position.tolist(), "rotation": v.rotation.tolist(),
                     "projection": v.projection.to_dict()} for v in scene.views],
                "distant_sources": [d.to_dict() for d in scene.distant_sources],
            },
        }
        if scene.surface_materials is not None:
            meta["scene"]["surface_materials"] = [asdict(m) for m in scene.surface_materials]
        arrays = {name: getattr(self, name) for name in _NODE_FIELDS + (_MATERIAL_FIELDS if self.materials else ())}
        arrays.update(
            triangles=scene.triangles, material=scene.material, reflectance=scene.reflectance,
            emitter=scene.emitter,
        )
        cache = self.surface_cache
        if cache is not None:
            meta["surface_cache"] = {"spacing": cache.spacing, "provenance": cache.provenance}
            arrays.update({f"cache_{name}": getattr(cache, name) for name in SurfaceCache.ARRAYS})
            meta["surface_cache"]["refine"] = cache.refine
        if self.node_hull is not None:
            arrays["node_hull"] = self.node_hull
        for k, lum in enumerate(scene.point_luminaires):
            p = lum.photometry
            arrays[f"table{k}_c"], arrays[f"table{k}_gamma"], arrays[f"table{k}_intensity"] = (
                p.c_angles, p.gamma_angles, p.candela)
        arrays["meta"] = np.frombuffer(json.dumps(meta).encode("utf-8"), dtype=np.uint8)
        with atomic_path(path) as temp, open(temp, "wb") as fh:
            np.savez_compressed(fh, **arrays)


def load_store(path):
    """Read a store written by :meth:`LsadStore.save`."""
    path = Path(path)
    if not path.is_file():
        raise BadInputError(f"LSAD store {path} does not exist")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise UnsupportedFileError(f"{path}: not a readable LSAD store ({exc})") from None
    try:
        meta = json.loads(arrays.pop("meta").tobytes().decode("utf-8"))
    except (KeyError, ValueError, UnicodeDecodeError):
        raise UnsupportedFileError(f"{path}: not an LSAD store (no header)") from None
    if meta.get("format") not in READABLE_FORMATS:
        raise UnsupportedFileError(f"{path}: unknown store format {meta.get('format')!r}")
    try:
        s = meta["scene"]
        emitter = arrays["emitter"]
        area = [AreaLuminaire(l["name"], l["flux"], np.flatnonzero(emitter == k),
                              math.inf if l.get("light_source_radius") is None else l["light_source_radius"])
                for k, l in enumerate(s["area_luminaires"])]
        points = []
        for k, l in enumerate(s["point_luminaires"]):
            photometry = Photometry(arrays[f"table{k}_c"], arrays[f"table{k}_gamma"],
                                    arrays[f"table{k}_intensity"], **l["photometry"])
            points.append(PointLuminaire(l["name"], np.asarray(l["position"]), photometry,
                                         np.asarray(l["frame"]), tuple(l["extent"]), l["multiplier"]))
        views = [View(v["name"], np.asarray(v["position"]), np.asarray(v["rotation"]),
                      projection_from_dict(v["projection"])) for v in s["views"]]
        materials = s.get("surface_materials")
        scene = Scene(arrays["triangles"], arrays["material"], s["material_names"],
                      arrays["reflectance"], emitter, area, points, views, name=s["name"],
                      distant_sources=[DistantSource.from_dict(d) for d in s.get("distant_sources", [])],
                      surface_materials=None if materials is None else [
                          Material(**{**m, "colour": tuple(m["colour"])}) for m in materials])
        if not scene.lambertian and meta["format"] == "lsadphoto-lsad-store/4":  # reciprocal, no ``direct``
            arrays["direct"] = np.zeros(len(arrays["coefficient"]), bool)
        nodes = {name: arrays[name] for name in _NODE_FIELDS + (() if scene.lambertian else _MATERIAL_FIELDS)}
        cache = None
        if "surface_cache" in meta:
            c = meta["surface_cache"]
            cache = SurfaceCache(spacing=c["spacing"], refine=c["refine"],
                                 provenance=c.get("provenance", {}),
                                 **{name: arrays[f"cache_{name}"] for name in SurfaceCache.ARRAYS
                                    # stores saved before the clearance load without it (∞)
                                    if name != "clearance" or "cache_clearance" in arrays})
    except KeyError as exc:
        raise UnsupportedFileError(f"{path}: LSAD store lacks {exc.args[0]!r}") from None
    hull = arrays.get("node_hull")
    if hull is not None and (hull.ndim != 2 or hull.shape[1:] != (3,) or hull.dtype.kind != "f"):
        raise UnsupportedFileError(f"{path}: the store's node hull is not an array of 3-D points "
                                   f"(shape {hull.shape}, {hull.dtype})")
    return LsadStore(scene, **nodes, chains=meta["chains"], batches=meta["batches"],
                     seed=meta["seed"], near_field=meta["near_field"],
                     fresnel_rule=meta.get("fresnel_rule", "reciprocal"),
                     provenance=meta.get("provenance", {}), surface_cache=cache, node_hull=hull)
