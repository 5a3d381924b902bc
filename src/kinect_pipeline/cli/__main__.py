"""``python -m kinect_pipeline.cli``: the same as the ``kinect-pipeline`` command."""

import sys

from . import main

sys.exit(main())
