"""End-to-end generation: condition → articulation tree → part latents → meshes → object.

    gen = Generator.load(GenerationConfig())                 # the shipped small model
    [res] = gen.generate("a cabinet with two drawers", seed=3)
    out = gen.export(res, "out/cabinet")                     # URDF + meshes + preview

Stages (timed into ``GeneratedObject.timings``, seconds): ``text_encoding`` (or
``image_encoding``), ``decoding`` (iterative decoding of the tree), ``diffusion`` (DDIM over
every part's latent, one batch per object), ``meshing`` (coarse-to-fine SDF + marching
cubes, fitted to the predicted boxes); ``refine`` (``model.refine``: layout before meshing,
floaters / simplification / carving / joint limits after); ``export`` is added by
:meth:`Generator.export`.
"""
from __future__ import annotations

import logging
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional, Union

import numpy as np

from model.core import ArticulatedObject, ObjectValidationError
from model.core.runtime import keep_heap_mapped, torch_threads
from model.pipeline.api import (ExportResult, GeneratedObject, GenerationConfig,
                                GenerationError)
from model.pipeline.part_pool import PartPool, default_workers
from model.data.prompt_size import (FRONT_UP_DIMS, height_said, says_knobs, usual_parts_text,
                                    width_said, with_lidded_size, with_usual_hinge,
                                    with_usual_keypad, with_usual_layout, with_usual_parts,
                                    with_usual_size)
from model.pipeline.prompt_structure import front_door_text, lids_as_front_doors, spatial_for
# checkpoint discovery and request checks, re-exported from their modules
from model.pipeline.checkpoints import (STAGES, WEIGHTS_DIR, check_codebooks,  # noqa: F401
                                        file_digest, find_checkpoints)
from model.pipeline.validate import MAX_PROMPT_CHARS, check_prompt, validate_config  # noqa: F401

log = logging.getLogger(__name__)


@dataclass
class _Loaded:
    paths: dict[str, Optional[Path]]
    hashes: dict[str, str] = field(default_factory=dict)
    load_seconds: float = 0.0


class Generator:
    """The three trained stages (+ the optional image model) and the generation loop."""

    def __init__(self, config: GenerationConfig, articulation, shape, image_model=None,
                 loaded: Optional[_Loaded] = None, image_shape=None):
        self.config = config
        self.articulation = articulation   # model.articulation.ArticulationModel
        self.shape = shape                 # model.geometry.ShapeModel
        self.image_model = image_model     # model.imaging.model.ImageArticulationModel | None
        # the shape prior the image model's part latents are for (the text model's unless the
        # folder has an image_prior/ sub-folder: pipeline.checkpoints.IMAGE_PRIOR_DIR)
        self.image_shape = image_shape if image_shape is not None else shape
        self.loaded = loaded or _Loaded(paths={})
        workers = config.mesh_workers if config.mesh_workers >= 0 else default_workers()
        self.parts = PartPool(workers)     # meshing lanes (part_pool.py)

    def close(self) -> None:
        """Stop the meshing helpers (also done when the generator is collected)."""
        self.parts.close()

    # -- loading ----------------------------------------------------------------------------
    @classmethod
    def load(cls, config: Optional[GenerationConfig] = None) -> "Generator":
        import torch

        from model.articulation import ArticulationModel
        from model.geometry import ShapeModel

        config = config or GenerationConfig()
        validate_config(config)
        torch.set_num_threads(max(1, int(config.threads)))
        keep_heap_mapped()                      # meshing buffers stay mapped (core.runtime)
        t0 = time.perf_counter()
        paths = find_checkpoints(config.checkpoint)
        try:
            shape = ShapeModel.load(paths["sdf"], paths["prior"])
            # refuses a transformer trained against another shape prior
            articulation = ArticulationModel.load(paths["transformer"],
                                                  prior=shape.info["accepts"])
        except GenerationError:
            raise
        except Exception as e:  # corrupt / mismatched checkpoints: say which stage
            raise GenerationError(f"could not load the model from {paths['transformer'].parent}: {e}") from e
        check_codebooks(articulation.cfg, shape, paths["transformer"], paths["prior"])
        image_model, image_shape = None, None
        if paths["image"] is not None:
            try:
                from model.imaging.model import load_image_model
                image_shape, prior = shape, paths["prior"]
                if paths["image_prior"] is not None:   # its own, older prior (image_prior/)
                    image_shape = ShapeModel.load(paths["image_sdf"], paths["image_prior"])
                    prior = paths["image_prior"]
                image_model = load_image_model(paths["image"],
                                               prior=image_shape.info["accepts"])
                check_codebooks(image_model.am.cfg, image_shape, paths["image"], prior)
            except Exception as e:
                image_model, image_shape = None, None
                log.warning("image model %s not loaded (%s); image requests will be refused",
                            paths["image"], e)
        articulation.encode_text(["warm up"])   # load the text encoder now, not on request 1
        loaded = _Loaded(paths=paths, hashes={k: file_digest(p) for k, p in paths.items() if p},
                         load_seconds=time.perf_counter() - t0)
        log.info("model loaded in %.2f s from %s", loaded.load_seconds, paths["transformer"].parent)
        gen = cls(config, articulation, shape, image_model, loaded, image_shape=image_shape)
        gen.parts.start()                       # helpers import now, not on request 1
        return gen

    @property
    def supports_image(self) -> bool:
        return self.image_model is not None

    # -- generation -------------------------------------------------------------------------
    def generate(self, text: Optional[str] = None, *, image=None, seed: int = 0, samples: int = 1,
                 keep: Optional[ArticulatedObject] = None,
                 structure=None, size=None) -> list[GeneratedObject]:
        """Generate ``samples`` objects for a text or an image (not both).

        Sample i uses seed ``seed + i`` everywhere, so the same seed gives the same object.
        ``keep`` (editing): the decoded trees start from this object's parts, which keep their
        meshes; only new parts get geometry. ``structure`` (a dict or its JSON text, see
        ``model.pipeline.api.parse_structure`` and docs/articulation.md): the parts every
        sample must have, forced during decoding; GenerationError before any decoding when
        the model cannot produce it. ``size`` (a dict or its JSON text, e.g. ``{"width":
        0.6}``, metres): the body's dimensions, over any the text states (docs/structure.md).
        """
        import torch

        from model.pipeline.api import parse_structure

        spec = None if structure is None else parse_structure(structure)
        seed = int(seed)
        trees, prompt, modality, timings = self.decode_trees(text, image=image, seed=seed,
                                                             samples=samples, keep=keep,
                                                             structure=spec, size=size)

        results = []
        for i, tree in enumerate(trees):
            tim = dict(timings)
            gen = torch.Generator().manual_seed(seed + i)
            shape = self.image_shape if modality == "image" else self.shape
            obj = self._geometry(tree, gen, tim, keep, shape)
            obj.name = _object_name(obj.category, seed + i)
            obj.metadata.update(prompt=prompt, seed=seed + i, modality=modality)
            if spec is not None:
                obj.metadata["structure"] = spec.to_dict()
            elif tree.structure is not None:      # the parts the prompt states, held
                obj.metadata["prompt_structure"] = tree.structure
            if tree.size:          # the body's, m (asked or stated)
                obj.metadata["size"] = _front_up_dims(tree.size) if tree.front_up else \
                    dict(tree.size)
            results.append(GeneratedObject(obj=obj, prompt=prompt, seed=seed + i, timings=tim))
        return results

    def decode_trees(self, text: Optional[str] = None, *, image=None, seed: int = 0,
                     samples: int = 1, keep: Optional[ArticulatedObject] = None,
                     structure=None, size=None) -> tuple[list, str, str, dict]:
        """The first stages of :meth:`generate` alone: condition -> decoded part trees
        (``model.articulation.DecodedTree``: labels, joint types, boxes; no shapes, no
        meshes). Returns (trees, prompt, modality, timings); the same seed gives the trees
        that :meth:`generate` meshes."""
        import torch

        from model.pipeline.api import parse_size, parse_structure

        if (text is None) == (image is None):
            raise GenerationError("give a text or an image (exactly one)")
        if not 1 <= int(samples) <= 16:
            raise GenerationError(f"samples must be between 1 and 16, got {samples}")
        given = None if size is None else parse_size(size)
        spec = splan = None
        if structure is not None:
            if keep is not None:
                raise GenerationError("structure cannot be combined with editing (keep)")
            spec = parse_structure(structure)
        seed = int(seed)
        cfg = self.config
        timings: dict[str, float] = {}
        t = time.perf_counter()
        if text is not None:
            prompt = check_prompt(text)
            with torch_threads(cfg.token_threads):
                cond, mask = self.articulation.encode_text([prompt])       # (1, L, D), (1, L)
            modality, decoder, counts = "text", self.articulation, None
            timings["text_encoding"] = time.perf_counter() - t
        else:
            if self.image_model is None:
                raise GenerationError("this model has no image stage (no image*.pt checkpoint)")
            from model.encoders.image import ImageInputError
            try:
                cond, mask, counts = self.image_model.condition(image, cfg.frame_images)   # (1, 49[+n], D)
            except ImageInputError as e:
                raise GenerationError(f"bad image: {e}") from e
            prompt = image if isinstance(image, str) else "<image>"
            modality, decoder = "image", self.image_model.am
            timings["image_encoding"] = time.perf_counter() - t
        if structure is not None:
            try:
                splan = decoder.resolve_structure(spec, max_nodes=cfg.max_nodes,
                                                  max_children=cfg.max_children)
            except ValueError as e:
                raise GenerationError(str(e)) from None
        stated, lidded = None, False
        if modality == "text" and keep is None and cfg.prompt_structure:
            from model.data.prompt_parse import parse_prompt
            said = with_usual_keypad(prompt, parse_prompt(prompt))
            usual = with_usual_parts(prompt, said)
            stated = with_usual_hinge(prompt, usual)
            if structure is None:     # (a structure given outright is the user's own)
                stated, lidded = lids_as_front_doors(stated)
            # the network reads the usual parts a bare name gets, or the cabinet a chest is
            # decoded as, named in the text
            reading = front_door_text(stated) if lidded else \
                usual_parts_text(prompt, said, usual) if structure is None else None
            if reading is not None:
                with torch_threads(cfg.token_threads):
                    cond, mask = self.articulation.encode_text([reading])
            if structure is None:
                spec, splan = self._stated_structure(stated, cond, mask, seed)

        t = time.perf_counter()
        S = int(samples)
        # text follows the transformer's START plan head; an image its model's count head
        # (without one it decodes freely: the START plan head reads images worse)
        plan = None
        if modality == "image" and modality in cfg.follow_plan and counts is not None:
            plan = counts.expand(S, -1)
        with torch_threads(cfg.token_threads):
            trees = decoder.decode(cond.expand(S, -1, -1), mask.expand(S, -1), seed=seed,
                                   max_nodes=cfg.max_nodes, max_depth=cfg.max_depth,
                                   max_children=cfg.max_children, modality=modality, keep=keep,
                                   temperature=cfg.structure_temperature,
                                   follow_plan=(_text_plan(cfg) if modality == "text"
                                                else False),
                                   plan=plan, structure=splan,
                                   sample_choices=cfg.sample_choices,
                                   sibling_room=cfg.sibling_room,
                                   dropout_sampling=cfg.layout_sampling == "always" or (
                                       cfg.layout_sampling == "structure" and splan is not None))
        timings["decoding"] = (time.perf_counter() - t) / S
        held = None if spec is None else parse_structure(spec).to_dict()
        for tree in trees:
            tree.structure = held
            tree.front_up = lidded and tree.category == "StorageFurniture"
            tree.knob_handles = stated is not None and tree.category == "StorageFurniture" \
                and says_knobs(prompt)
            tree.spatial = with_usual_layout(prompt, tree.category, spatial_for(
                stated.spatial, tree.category)) if stated is not None else None
            if tree.front_up:      # the chest's size, on the cabinet it is decoded as
                said = with_lidded_size(prompt, stated.size, tree.tokens[0, :3])
                tree.size = _front_up_dims({**said, **(given or {})})
            else:
                said = with_usual_size(prompt, tree.category, stated.size,
                                       decoded=tree.tokens[0, :3],
                                       spatial=stated.spatial) if stated else {}
                tree.size = {**said, **(given or {})} or None
            tree.height_said = bool(given and ("height" in given or "length" in given)) or (
                stated is not None and height_said(prompt, tree.category, stated.size))
            tree.width_said = bool(given and ("width" in given or "length" in given)) or (
                stated is not None and width_said(prompt, tree.category, stated.size))
        return trees, prompt, modality, timings

    def _stated_structure(self, expected, cond, mask, seed: int):
        """The structure a text prompt states outright (``expected``: its parse, see
        model.pipeline.prompt_structure), as (structure dict, StructurePlan), or (None, None)
        when it states no part count or none this model can hold. The network's own decoding
        of the prompt (first sample) gives the category when the prompt names none, and the
        counts of the parts it leaves open."""
        from model.pipeline.prompt_structure import resolve_prompt_structure, stated_counts

        if not stated_counts(expected):
            return None, None
        cfg, am = self.config, self.articulation
        cats = sorted(set(am.table_categories))
        with torch_threads(cfg.token_threads):
            [free] = am.decode(cond, mask, seed=seed, max_nodes=cfg.max_nodes,
                               max_depth=cfg.max_depth, max_children=cfg.max_children,
                               modality="text", temperature=cfg.structure_temperature,
                               follow_plan=_text_plan(cfg))
        order = ([expected.category] if expected.category in cats else
                 [free.category] + [c for c in cats if c != free.category])
        return resolve_prompt_structure(am, expected, order, max_nodes=cfg.max_nodes,
                                        max_children=cfg.max_children, own_reading=free)

    def layout(self, tree, report: Optional[dict] = None,
               refine: Optional[bool] = None) -> ArticulatedObject:
        """A decoded tree as the object the product meshes: its boxes and joints, with the
        layout refinement when ``refine`` (default: the config's) — the arrangements the
        prompt states first (model.refine.arrange, with ``prompt_structure``), then
        model.refine.refine_layout, then the hinge sides a structure asked for, then door
        handles to their free edge (free_edge_handles). A size the prompt states is given to
        the body first, refined or not (model.refine.size), unless parts are kept. Last, the
        object is placed in the data's frame, refined or not (base on z = 0, body centred on
        the z axis: model.refine.size.place_on_floor), unless parts are kept."""
        obj = tree.to_object()
        report = {} if report is None else report
        kept = bool(np.any(tree.kept))
        if tree.size and not kept:
            from model.refine.size import scale_to_size
            report["size"] = scale_to_size(obj, tree.size)
        if self.config.refine if refine is None else refine:
            self._refine_layout(obj, tree, report)
        if not kept:
            from model.refine.size import place_on_floor
            report["placed"] = place_on_floor(obj)
        return obj

    def _refine_layout(self, obj: ArticulatedObject, tree, report: dict) -> None:
        """The layout refinement steps of :meth:`layout`, in place."""
        from model.refine import (arrange_stated, door_beside_controls, free_edge_handles,
                                  knob_handles, match_handles, place_stated_sides,
                                  refine_layout, safe_keypads)
        from model.refine.size import (cap_drawer_height, lower_drawer_row, row_thin_drawers,
                                       widen_door_row)
        stated = tree.spatial if self.config.prompt_structure else None
        report["arranged"] = arrange_stated(obj, stated) + safe_keypads(obj, stated)
        report["layout"] = refine_layout(obj, stated=stated)
        report["layout"]["drawer_row_lowered"] = None if tree.height_said else \
            lower_drawer_row(obj)
        report["layout"]["door_row_widened"] = None if tree.width_said else \
            widen_door_row(obj)
        report["layout"]["drawers_shortened"] = cap_drawer_height(obj)
        report["layout"]["thin_drawers_side_by_side"] = row_thin_drawers(obj, stated)
        if stated:
            report["arranged"] += place_stated_sides(obj, stated)
        report["arranged"] += door_beside_controls(obj, stated)
        _keep_hinge_sides(obj, tree.hinges)
        report["layout"]["handles_to_free_edge"] = free_edge_handles(obj, stated)
        report["layout"]["handles_matched"] = match_handles(obj, stated)
        if tree.knob_handles:
            report["layout"]["knob_handles"] = len(knob_handles(obj))

    def _geometry(self, tree, gen, timings: dict, keep: Optional[ArticulatedObject],
                  shape) -> ArticulatedObject:
        """Latents for every new part in one batch from ``shape`` (the shape prior the tree's
        decoder was trained against), meshes fitted to the predicted boxes."""
        import torch
        import trimesh

        from model.geometry.data import label_text
        from model.pipeline.part_finish import PartTask

        cfg = self.config
        refine_s, refined = 0.0, {}
        t = time.perf_counter()
        obj = self.layout(tree, report=refined, refine=cfg.refine and keep is None)
        refine_s += time.perf_counter() - t
        new = [k for k in range(tree.num_nodes) if not (len(tree.kept) and tree.kept[k])]
        texts = [label_text(tree.category, tree.labels[k]) for k in new]
        t = time.perf_counter()
        if new:
            if tree.P_logits is None:      # the no-shape-prior ablation regresses z directly
                z = torch.as_tensor(tree.z[new], dtype=torch.float32)
            else:
                P = torch.as_tensor(tree.P_logits[new], dtype=torch.float32)      # (K, C, N)
                cs = torch.as_tensor(tree.cs[new], dtype=torch.float32)           # (K, 64)
                with torch_threads(cfg.token_threads):
                    z = shape.sample_from_logits(P, cs, steps=cfg.steps, tau=cfg.temperature,
                                                 guidance=cfg.guidance, generator=gen)
            if cfg.geometry == "retrieve":
                z, _ = shape.retrieve(z, texts)
        timings["diffusion"] = time.perf_counter() - t

        t = time.perf_counter()
        copy_of = instances(obj, new) if cfg.instances else {}
        if copy_of:
            z = z.clone()
            for k, rep in copy_of.items():
                z[new.index(k)] = z[new.index(rep)]
        meshed = [n for n, k in enumerate(new) if k not in copy_of]
        with torch_threads(cfg.threads):
            res = [part_resolution(obj.parts[new[n]].bbox_size, cfg) for n in meshed]
            grids = shape.decode_grids(z[meshed], resolution=res) if meshed else []
        tasks = [PartTask(new[n], g, obj.parts[new[n]].bbox_center, obj.parts[new[n]].bbox_size,
                         prepare=cfg.refine or cfg.face_budget > 0, floaters=cfg.refine,
                         simplify=cfg.face_budget > 0)
                 for n, g in zip(meshed, grids)]
        done = {d.index: d for d in self.parts.finish(tasks)}
        for k, rep in copy_of.items():
            done[k] = done[rep].moved(k, obj.parts[k].bbox_center - obj.parts[rep].bbox_center)
        fallbacks, prepared = [], {}
        for k, d in ((k, done[k]) for k in new):
            part = obj.parts[k]
            if not d.ok:
                # No surface in the decoded field: keep the part usable as its box.
                fallbacks.append(part.name)
                m = trimesh.creation.box(extents=np.maximum(part.bbox_size, 1e-3))
                m.apply_translation(part.bbox_center)
            else:
                m = d.mesh()
                part.collision = d.collision()
                if d.prepared is not None:
                    prepared[k] = d.prepared
            part.mesh = m
            part.latent = z[new.index(k)].numpy().copy()
        if keep is not None:
            for k in range(tree.num_nodes):
                if len(tree.kept) and tree.kept[k]:
                    src = keep.parts[int(tree.source_index[k])]
                    obj.parts[k].mesh = src.mesh
                    obj.parts[k].name = src.name
                    obj.parts[k].joint = src.joint
        timings["meshing"] = time.perf_counter() - t
        if new and len(fallbacks) == len(new):
            raise GenerationError("the shape prior produced no surface for any part")
        if fallbacks:
            log.warning("parts %s had no surface; exported as their boxes", fallbacks)
        obj.metadata["box_fallback_parts"] = fallbacks
        kept = frozenset(k for k in range(tree.num_nodes) if len(tree.kept) and tree.kept[k])
        if tree.front_up:        # a chest with a lid: the cabinet it was decoded as, turned
            from model.refine.orient import turn_front_up
            obj.metadata["turned_front_up"] = turn_front_up(obj, prepared)
        if cfg.refine:
            from model.refine import RefineConfig, refine_meshes
            t = time.perf_counter()
            refined["meshes"] = refine_meshes(obj, RefineConfig(face_budget=cfg.face_budget),
                                              frozen=kept, prepared=prepared)
            refine_s += time.perf_counter() - t
            timings["refine"] = refine_s
            obj.metadata["refine"] = refined
        elif cfg.face_budget > 0:    # raw output: the face budget and nothing else
            from model.refine import simplify_meshes
            t = time.perf_counter()
            obj.metadata["simplify"] = simplify_meshes(obj, cfg.face_budget, frozen=kept,
                                                       prepared=prepared)
            timings["simplify"] = time.perf_counter() - t
        if tree.front_up:
            from model.refine.orient import doors_to_lids
            doors_to_lids(obj)
        _unique_names(obj)
        try:
            obj.validate()
        except ObjectValidationError as e:
            raise GenerationError(f"generated object is invalid: {e}") from e
        return obj

    # -- export -----------------------------------------------------------------------------
    def export(self, result: GeneratedObject, out_dir: Union[str, os.PathLike], *,
               preview: bool = True, mesh_uri: str = "file") -> ExportResult:
        """URDF + meshes + metadata as one atomic folder (timed as "export"), then, with
        ``preview``, preview.png written into it atomically (timed as "preview"): robots
        need the folder, people the picture, so the picture does not hold up the URDF."""
        from model.export import CollisionConfig, export_object

        t = time.perf_counter()
        prov = {"prompt": result.prompt, "seed": result.seed,
                "model": {k: f"{p.name}@{self.loaded.hashes.get(k, '?')}"
                          for k, p in self.loaded.paths.items() if p},
                "config": asdict(self.config)}
        out = export_object(result.obj, out_dir, mesh_format=self.config.mesh_format,
                            provenance=prov, preview=False, mesh_uri=mesh_uri,
                            collision=CollisionConfig(method=self.config.collision))
        result.timings["export"] = time.perf_counter() - t
        if preview:
            self.write_preview(result, out)
        return out

    def write_preview(self, result: GeneratedObject, exported: ExportResult,
                      interrupt=None) -> Optional[str]:
        """preview.png (openness 0 / 0.5 / 1) into an exported folder; sets its path. With
        ``interrupt`` (asked between the views) it may stop early and return None."""
        from model.export.render import write_preview

        t = time.perf_counter()
        path = write_preview(result.obj, Path(exported.out_dir) / "preview.png",
                             interrupt=interrupt)
        if path is None:
            return None
        exported.preview_path = path
        result.timings["preview"] = time.perf_counter() - t
        return path


def _front_up_dims(size: dict) -> dict:
    """Body dimensions of a chest (front up) as those of the cabinet it is decoded as, and
    back (FRONT_UP_DIMS swaps height and depth)."""
    return {FRONT_UP_DIMS.get(k, k): v for k, v in size.items()}


def _text_plan(cfg: GenerationConfig):
    """``decode``'s ``follow_plan`` for text: the plan held ("hold"), followed softly
    (True), or not used (False)."""
    if "text" not in cfg.follow_plan:
        return False
    return "hold" if cfg.hold_plan else True


def _keep_hinge_sides(obj: ArticulatedObject, sides: Optional[list]) -> None:
    """Hinge sides a structure asked for (DecodedTree.hinges), kept through layout refinement:
    refinement puts a hinge on the box edge nearest the predicted origin, and a box it moves
    past that origin would swap the side; such a joint is mirrored back (set_hinge)."""
    if not sides:
        return
    from model.articulation.decode import set_hinge
    from model.pipeline.api import hinge_side
    for part, side in zip(obj.parts, sides):
        if side is None or hinge_side(part.token()) == side:
            continue
        tok = set_hinge(part.token(), side)
        part.joint.origin, part.joint.axis = tok[6:9].copy(), tok[9:12].copy()


def part_resolution(size, cfg: GenerationConfig) -> int:
    """Marching-cubes cells per side for a part of box ``size`` (m): enough for cells of
    ``cfg.mesh_cell`` along its longest side, from 16 up to ``cfg.resolution`` in powers of
    two (the coarse-to-fine ladder); ``mesh_cell`` 0 meshes every part at ``resolution``."""
    if cfg.mesh_cell <= 0:
        return int(cfg.resolution)
    need = float(np.max(size)) / cfg.mesh_cell
    res = 16
    while res < need and res * 2 <= cfg.resolution:
        res *= 2
    return min(res, int(cfg.resolution))


def instances(obj: ArticulatedObject, parts: list[int], tol: float = 1e-4) -> dict[int, int]:
    """Parts among ``parts`` that repeat an earlier one — same label, box sides within
    ``tol`` m — mapped to that first one. A stack of equal drawers, the handles on them and
    a row of knobs share one shape (as built furniture and appliances do), and the pipeline
    meshes it once."""
    first: list[int] = []
    out: dict[int, int] = {}
    for k in parts:
        p = obj.parts[k]
        rep = next((r for r in first if obj.parts[r].label == p.label and np.all(
            np.abs(obj.parts[r].bbox_size - p.bbox_size) <= tol)), None)
        if rep is None:
            first.append(k)
        else:
            out[k] = rep
    return out


def _object_name(category: str, seed: int) -> str:
    slug = "".join(c if c.isalnum() else "_" for c in (category or "object").lower()).strip("_")
    return f"{slug or 'object'}_s{seed}"


def _unique_names(obj: ArticulatedObject) -> None:
    seen: dict[str, int] = {}
    for p in obj.parts:
        base = p.name
        if base in seen:
            seen[base] += 1
            p.name = f"{base}_{seen[base]}"
        else:
            seen[base] = 0


_DEFAULT: dict[tuple, Generator] = {}


def default_generator(config: Optional[GenerationConfig] = None) -> Generator:
    """Process-wide cached Generator for a config (the shipped model by default)."""
    config = config or GenerationConfig()
    key = tuple(sorted(asdict(config).items()))
    if key not in _DEFAULT:
        _DEFAULT[key] = Generator.load(config)
    return _DEFAULT[key]


def generate_to_folder(text: Optional[str], out_dir: Union[str, os.PathLike], *, image=None,
                       seed: int = 0, samples: int = 1,
                       config: Optional[GenerationConfig] = None) -> list[ExportResult]:
    """Convenience: generate and export each sample to ``out_dir`` (``sample_<i>`` when >1)."""
    gen = default_generator(config)
    results = gen.generate(text, image=image, seed=seed, samples=samples)
    outs = []
    for i, r in enumerate(results):
        d = Path(out_dir) if len(results) == 1 else Path(out_dir) / f"sample_{i}"
        outs.append(gen.export(r, d))
    return outs


__all__ = ["Generator", "default_generator", "generate_to_folder", "find_checkpoints",
           "check_prompt", "validate_config"]
