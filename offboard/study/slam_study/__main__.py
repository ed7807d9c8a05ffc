"""`python -m slam_study ...`: see cli.py."""

import sys

from slam_study.cli import main

sys.exit(main())
