import sys

from ray3d.cli import main

sys.exit(main())
