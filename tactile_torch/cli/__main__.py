"""``python -m tactile_torch.cli``: the same as the ``tactile-torch`` console script."""

import sys

from . import main

sys.exit(main())
