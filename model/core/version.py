"""The source version of the model package (``model.__version__``), here so that any layer
can read it without importing the package root."""
__version__ = "0.1.0"
