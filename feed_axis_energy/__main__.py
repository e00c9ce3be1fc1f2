"""Allow ``python -m feed_axis_energy``."""
import sys

from feed_axis_energy.cli import main

sys.exit(main())
