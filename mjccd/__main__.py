"""``python -m mjccd`` is the ``mjccd`` command."""
import sys

from mjccd.cli import main

sys.exit(main())
