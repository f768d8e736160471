#!/usr/bin/env python3
"""Write the web page's colours, ``ird_ros/web/static/colors.js``, from ``ird_core/style.py``.

    python scripts/gen_web_style.py          # (re)write the file
    python scripts/gen_web_style.py --check  # exit 1 if the committed file differs from the style

The page (``ird_ros/web/static/index.html``) loads ``colors.js`` before ``app.js``, which draws
terrains, option paths and the risk map in ``IRD_STYLE``'s colours, so the page and every picture
share :mod:`ird_core.style`. ``tests/test_picture_style.py`` holds the committed file equal to
the generated text.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ird_core.style import web_colors_js

TARGET = Path(__file__).resolve().parents[1] / "ird_ros" / "web" / "static" / "colors.js"


def main(argv: list[str] | None = None) -> int:
    """Write (or with ``--check`` compare) :data:`TARGET`; exit status 0, or 1 when stale."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="only compare; exit 1 if the file is stale")
    args = parser.parse_args(argv)
    text = web_colors_js()
    if args.check:
        current = TARGET.read_text(encoding="utf-8") if TARGET.exists() else ""
        if current != text:
            print(f"{TARGET} is stale: run python scripts/gen_web_style.py", file=sys.stderr)
            return 1
        return 0
    TARGET.write_text(text, encoding="utf-8")
    print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
