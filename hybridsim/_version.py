"""The package version: the one place it is written.

``pyproject.toml`` reads it (``[tool.setuptools.dynamic]``) and
``hybridsim.__version__`` re-exports it. A ``.devN`` suffix marks work after
the last release; ``CHANGELOG.md`` lists it under *Unreleased*.
"""

__version__ = "0.2.0.dev0"
