"""`python3 -m ecam.app ...` is the `ecam` command."""

import sys

from .cli import main

sys.exit(main())
