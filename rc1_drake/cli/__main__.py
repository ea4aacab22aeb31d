"""python -m rc1_drake.cli"""

import sys

from . import main

sys.exit(main())
