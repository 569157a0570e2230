"""Entry point for ``python -m graspstab.assets``."""

import sys

from graspstab.assets.cli import main

sys.exit(main())
