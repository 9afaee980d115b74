"""`artformer train image`: the image trainer's command (model.imaging.commands: training,
or --eval of a checkpoint on held-out renders) plus ``--eval CKPT --pipeline N``, which runs
N held-out images through the whole generator and export and reports POR, validity and
structure (model.metrics.image_pipeline). In the app layer because that check drives the
pipeline and the metrics, which sit above the imaging package.

    artformer train image --eval shipped --pipeline 24 --data data/prepared/v1 \
        --renders data/renders/v1 --split test
"""
from __future__ import annotations

from model.imaging.commands import image_parser, print_report, train_image_main


def parser():
    ap = image_parser()
    ap.add_argument("--pipeline", type=int, metavar="N", default=0,
                    help="--eval: instead, run N test images through the whole generator "
                         "(the --eval folder or 'shipped') and report POR, validity, structure")
    return ap


def main(argv: list[str]) -> int:
    import logging
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if argv[:2] == ["train", "image"]:
        argv = argv[2:]
    args = parser().parse_args(argv)
    if not (args.eval and args.pipeline):
        return train_image_main(argv, args)
    from model.metrics.image_pipeline import image_pipeline_report
    rep = image_pipeline_report(args.data, args.renders, split=args.split, n=args.pipeline,
                                checkpoint=None if args.eval == "shipped" else args.eval,
                                seed=args.eval_seed, progress=not args.no_progress)
    print_report(rep, args.json)
    return 0
