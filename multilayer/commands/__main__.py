"""``python -m multilayer.commands``: the ``multilayer`` console script (:func:`multilayer.commands.console`)."""

import sys

from multilayer.commands import console

sys.exit(console())
