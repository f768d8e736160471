#!/usr/bin/env python3
"""Write a generated Lavaland instance as a world file that ``--world`` loads: ``ird-export-world``.

The program is ``ird_core.worlds.export.main``; ``--help`` lists the flags.
"""

import sys

from ird_core.worlds.export import main

if __name__ == "__main__":
    sys.exit(main())
