"""Kept so that ``import cloudmeta.engine`` goes on working: the module is now ``cloudmeta.api.rays``."""
import importlib
import sys

sys.modules[__name__] = importlib.import_module("cloudmeta.api.rays")
