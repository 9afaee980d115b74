"""`artformer train transformer`: the articulation trainer's command
(model.articulation.commands) plus ``--eval CKPT``, the structure alignment of a checkpoint
on a held-out split (model.metrics.text_alignment: the record's structure and the metrics'
prompt alignment). In the app layer because that report scores with the metrics, which sit
above the articulation package.

    artformer train transformer --eval runs/transformer_small/transformer.pt \
        --data data/prepared/v1 --split test      # structure-alignment figure of a checkpoint
"""
from __future__ import annotations

from model.articulation.commands import main as train_main
from model.articulation.commands import parser as train_parser


def parser():
    ap = train_parser()
    ap.add_argument("--eval", metavar="CKPT", help="measure structure alignment of CKPT on --split")
    ap.add_argument("--split", default="test")
    ap.add_argument("--lengths", default="all",
                    help="description lengths for --eval (comma list or 'all')")
    ap.add_argument("--limit", type=int, default=0, help="--eval: at most this many objects")
    ap.add_argument("--eval-seed", type=int, default=0)
    ap.add_argument("--temperature", type=float, default=1.0)
    ap.add_argument("--follow-plan", action="store_true",
                    help="--eval: decode with END decisions held to the START plan head")
    ap.add_argument("--hold-plan", dest="follow_plan", action="store_const", const="hold",
                    help="--eval: decode again with the plan head's counts held as a structure "
                         "(decode(follow_plan='hold'))")
    ap.add_argument("--json", metavar="PATH", help="--eval: write the report as JSON")
    return ap


def main(argv: list[str]) -> int:
    import json
    import logging
    from pathlib import Path
    if argv[:2] == ["train", "transformer"]:
        argv = argv[2:]
    args = parser().parse_args(argv)
    if not args.eval:
        return train_main(argv, args)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    from model.metrics.text_alignment import alignment_report
    lengths = None if args.lengths == "all" else args.lengths.split(",")
    rep = alignment_report(args.eval, args.data, split=args.split, lengths=lengths,
                           limit=args.limit, seed=args.eval_seed, temperature=args.temperature,
                           follow_plan=args.follow_plan, progress=not args.no_progress)
    print(json.dumps({k: v for k, v in rep.items() if k != "rows"}, indent=1))
    if args.json:
        Path(args.json).write_text(json.dumps(rep, indent=1))
    return 0
