"""docs/figures/framing.png: a test render, the same render at 0.3 of a larger picture (a photo
from further away) as the encoder would read it whole, and as framing crops it.
Usage: python scripts/framing_figure.py [--render data/renders/v1/objects/000104/0.png]"""
import argparse

import numpy as np
from PIL import Image, ImageDraw

from model.encoders.framing import frame_object
from model.encoders.image import square_resize, to_rgb_float
from model.imaging.evaluate import farther_view


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--render", default="data/renders/v1/objects/000104/0.png")
    ap.add_argument("--share", type=float, default=0.3)
    ap.add_argument("--out", default="docs/figures/framing.png")
    args = ap.parse_args()
    far = farther_view(args.render, args.share)
    panels = [("render (224 px)", to_rgb_float(args.render)),
              (f"at {args.share} of a {far.shape[0]}-px photo, read whole", square_resize(far)),
              ("the same photo framed", square_resize(frame_object(far)))]
    sheet = Image.new("RGB", (3 * 236, 252), "white")
    draw = ImageDraw.Draw(sheet)
    for k, (title, rgb) in enumerate(panels):
        sheet.paste(Image.fromarray(np.clip(rgb * 255 + 0.5, 0, 255).astype(np.uint8)), (k * 236 + 6, 24))
        draw.text((k * 236 + 6, 6), title, fill="black")
    sheet.save(args.out)
    print(args.out)


if __name__ == "__main__":
    main()
