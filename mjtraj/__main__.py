"""`python -m mjtraj`: the mjtraj command."""

import sys

from mjtraj.cli import main

sys.exit(main())
