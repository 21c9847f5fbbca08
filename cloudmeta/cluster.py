"""Kept so that ``import cloudmeta.cluster`` goes on working: the module is now ``cloudmeta.api.cluster``."""
import importlib
import sys

sys.modules[__name__] = importlib.import_module("cloudmeta.api.cluster")
