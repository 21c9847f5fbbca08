"""Kept so that ``import cloudmeta.io`` goes on working: the module is now ``cloudmeta.api.io``."""
import importlib
import sys

sys.modules[__name__] = importlib.import_module("cloudmeta.api.io")
