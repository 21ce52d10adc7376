import os
import sys
from pathlib import Path

from hypothesis import settings

# Make tests/reference.py importable as `reference`.
sys.path.insert(0, str(Path(__file__).parent))

# CI explores the same examples on every run (a red CI must be reproducible); locally,
# hypothesis keeps exploring new ones.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
