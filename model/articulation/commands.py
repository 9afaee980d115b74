"""`artformer train transformer ...` — train the articulation transformer.

    artformer train transformer --data data/prepared/v1 --prior model/weights/prior_small.pt \
        --sdf model/weights/sdf_small.pt --preset small --out runs/transformer_small \
        [--resume] [--ablation none|no_tpe|one_codebook|no_shape_prior] [--steps N] [--minutes M] \
        [--extra-train data/prepared/v1x ... [--extra-wordings N]]   # more training objects

The command's ``--eval CKPT`` (structure alignment of a checkpoint, scored with the metrics'
prompt parser) is added above the metrics, in model.app.train_transformer.
"""
from __future__ import annotations

import argparse
import logging
import shlex
from pathlib import Path


def parser() -> argparse.ArgumentParser:
    """The training options of `artformer train transformer`."""
    from .config import ABLATIONS, PRESETS  # light: no torch network import
    ap = argparse.ArgumentParser(prog="artformer train transformer",
                                 description="Train the articulation transformer on a prepared "
                                             "dataset, or --eval a checkpoint's structure alignment.")
    ap.add_argument("--data", default="data/prepared/v1", help="prepared dataset folder")
    ap.add_argument("--prior", default="model/weights/prior_small.pt",
                    help="shape-prior checkpoint (P_gt and c_s targets); 'none' = stand-in "
                         "targets without a prior (development only)")
    ap.add_argument("--sdf", default="model/weights/sdf_small.pt",
                    help="SDF auto-encoder checkpoint (part latents z)")
    ap.add_argument("--preset", default="small", choices=sorted(PRESETS))
    ap.add_argument("--out", default="runs/transformer_small")
    ap.add_argument("--init", metavar="CKPT", help="start from the weights of CKPT (fine-tune; "
                                                   "tensors whose shapes differ are skipped)")
    ap.add_argument("--extra-train", metavar="DATA", action="append", default=[],
                    help="another prepared dataset (own data version) whose objects, all "
                         "splits, are added to the training set (repeatable); validation "
                         "stays --data's val split")
    ap.add_argument("--extra-wordings", type=int, default=0, metavar="N",
                    help="keep only the first N wordings of each description length of the "
                         "--extra-train objects (fewer text states to encode and cache; "
                         "default 0 = all)")
    ap.add_argument("--ablation", default="none", choices=ABLATIONS)
    add_training_args(ap)
    ap.add_argument("--text-encoder", help="'all-minilm-l6-v2' or a local transformers folder")
    ap.add_argument("--half", metavar="PATH", help="also write an fp16 copy of the final "
                                                   "checkpoint to PATH (the shipped file)")
    return ap


def add_training_args(ap: argparse.ArgumentParser) -> None:
    """The flags of the shared training loop and the TrainConfig overrides that the text and
    image trainers both take."""
    ap.add_argument("--resume", action="store_true", help="continue from OUT/last.pt")
    ap.add_argument("--chunk-minutes", type=float, default=0.0, metavar="M",
                    help="stop after M minutes of this process, checkpoint written; --resume "
                         "continues (the schedule follows --steps / --minutes)")
    ap.add_argument("--steps", type=int, help="override max_steps")
    ap.add_argument("--minutes", type=float, help="override the wall-clock budget (0 = none)")
    ap.add_argument("--batch-size", type=int)
    ap.add_argument("--lr", type=float)
    ap.add_argument("--warmup", type=int, help="override warmup_steps")
    ap.add_argument("--own-inputs", type=float, metavar="SHARE",
                    help="scheduled sampling: share of the objects per batch whose nodes carry "
                         "the network's own articulation predictions (default 0)")
    ap.add_argument("--token-frame", choices=("absolute", "parent"),
                    help="the frame of the part tokens: 'parent' gives boxes relative to the "
                         "parent's box and joint origins relative to the part's own box "
                         "(model.articulation.frames; default absolute)")
    ap.add_argument("--art-modes", type=int, metavar="K",
                    help="articulation head with K candidate tokens per part, one drawn when "
                         "decoding (default 1: one regressed token)")
    ap.add_argument("--mode-weight", type=float, metavar="W",
                    help="--art-modes: weight of the cross-entropy on the best mode (default 1)")
    ap.add_argument("--place-bins", action="store_const", const=True,
                    help="with --token-frame parent: a head classifies each coordinate of "
                         "the joint origin (on a face / the centre line of the part's box) "
                         "and of the box centre (touching or flush with a face of the "
                         "parent's box, centred) or elsewhere; decoding puts it exactly there")
    ap.add_argument("--seed", type=int)
    ap.add_argument("--threads", type=int)
    ap.add_argument("--no-progress", action="store_true")


def training_overrides(args: argparse.Namespace, **more) -> dict:
    """TrainConfig fields set by the flags of ``add_training_args`` (and ``more``)."""
    given = {"max_steps": args.steps, "max_minutes": args.minutes, "batch_size": args.batch_size,
             "lr": args.lr, "warmup_steps": args.warmup, "own_inputs": args.own_inputs,
             "token_frame": args.token_frame, "art_modes": args.art_modes,
             "w_mode": args.mode_weight, "place_bins": args.place_bins, "seed": args.seed,
             "threads": args.threads, **more}
    return {k: v for k, v in given.items() if v is not None}


def make_targets(prior: str, sdf: str, net_cfg):
    from .targets import PriorTargets, StandInTargets
    if prior.lower() == "none":
        logging.getLogger(__name__).warning(
            "training with STAND-IN targets (no shape prior): for development and tests only")
        return StandInTargets(z_dim=net_cfg.z_dim, num_codebooks=max(net_cfg.num_codebooks, 1),
                              codebook_size=net_cfg.codebook_size, cs_dim=net_cfg.cs_dim)
    for p in (prior, sdf):
        if not Path(p).exists():
            raise SystemExit(f"artformer train transformer: {p} does not exist; train the shape "
                             f"prior first (`artformer train sdf` / `artformer train prior`) "
                             f"or pass --prior none for stand-in targets")
    return PriorTargets(prior, sdf)


def main(argv: list[str], args: argparse.Namespace | None = None) -> int:
    """Train; ``args``: ``argv`` already parsed by a parser that extends ``parser()``."""
    if argv[:2] == ["train", "transformer"]:
        argv = argv[2:]
    args = args or parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    from .config import preset
    net_cfg, tc = preset(args.preset, args.ablation,
                         **training_overrides(args, text_encoder=args.text_encoder))
    from .train import RunConfig, train
    targets = make_targets(args.prior, args.sdf, net_cfg)
    command = "artformer train transformer " + " ".join(shlex.quote(a) for a in argv)
    path = train(RunConfig(data=args.data, out=args.out, net=net_cfg, train=tc, targets=targets,
                           resume=args.resume, init=args.init, ablation=args.ablation,
                           command=command, extra=list(args.extra_train),
                           extra_wordings=args.extra_wordings, chunk_minutes=args.chunk_minutes,
                           progress=not args.no_progress))
    if args.half:
        from .checkpoint import build_network, read_checkpoint, save_checkpoint
        ck = read_checkpoint(path)
        net = build_network(ck)
        keep = {k: ck[k] for k in ("ablation", "targets", "elapsed", "history", "init",
                                   "extra_train") if k in ck}
        save_checkpoint(args.half, net, stats=ck["stats"], label_table=ck["label_table"],
                        text_encoder=ck["text_encoder"], data_version=ck["data_version"],
                        seed=ck["seed"], command=ck["command"], step=ck["step"],
                        train_config=ck["train_config"], extra=keep, half=True,
                        prior=ck.get("prior", ""), device=ck.get("device", "cpu"),
                        recipe=ck.get("recipe", []))
        print(f"fp16 copy: {args.half}")
    print(f"checkpoint: {path}")
    return 0
