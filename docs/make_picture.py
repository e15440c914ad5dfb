"""Downsize a plot for the README and the manual's front page: ``make picture`` runs it.

``python docs/make_picture.py SRC.png DST.png [--width 1200] [--max-kb 250]``: scales ``SRC`` to
``--width`` pixels (never up), reduces it to a 256-colour palette (matplotlib plots have few
colours, so nothing visible is lost) and writes an optimised PNG. While the file is over
``--max-kb`` it tries again 10 % narrower. Uses Pillow, which matplotlib already depends on.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

from PIL import Image

#: Narrowest image worth committing [px]: below this the plot's labels stop being readable.
MIN_WIDTH_PX = 700


def downsize(src: Path, width_px: int, max_kb: float) -> tuple[bytes, tuple[int, int]]:
    """The PNG bytes of ``src`` scaled to at most ``width_px`` wide and, if possible, ``max_kb``."""
    image = Image.open(src).convert("RGB")
    width = min(width_px, image.width)
    while True:
        height = round(image.height * width / image.width)
        small = image.resize((width, height), Image.Resampling.LANCZOS)
        small = small.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        buf = io.BytesIO()
        small.save(buf, format="PNG", optimize=True)
        if buf.tell() <= max_kb * 1024 or width <= MIN_WIDTH_PX:
            return buf.getvalue(), (width, height)
        width = max(MIN_WIDTH_PX, int(width * 0.9))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("src", type=Path)
    ap.add_argument("dst", type=Path)
    ap.add_argument("--width", type=int, default=1200, help="largest width [px] (default 1200)")
    ap.add_argument("--max-kb", type=float, default=250.0, help="largest file size [KiB] (default 250)")
    args = ap.parse_args(argv)
    if not args.src.is_file():
        print(f"make_picture: error: {args.src} not found (run the demo plan first)", file=sys.stderr)
        return 2
    data, (w, h) = downsize(args.src, args.width, args.max_kb)
    args.dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.dst.with_name(f".{args.dst.name}.tmp")
    tmp.write_bytes(data)
    tmp.replace(args.dst)
    print(f"wrote {args.dst}: {w}×{h} px, {len(data) / 1024:.0f} KiB")
    if len(data) > args.max_kb * 1024:
        print(f"make_picture: note: over {args.max_kb:.0f} KiB even at {w} px", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
