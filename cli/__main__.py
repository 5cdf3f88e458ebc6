"""``python -m photogram_cli``: the same as the ``photogram`` command."""

import sys

from photogram_cli.main import main

sys.exit(main())
