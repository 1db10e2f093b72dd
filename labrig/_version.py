"""labrig's version, in a module of its own: the recording, the model and the analysis
stamp it into the files they write without importing the package's face, and
pyproject.toml reads it from here (``[tool.setuptools.dynamic]``)."""

__version__ = "0.1.0"
