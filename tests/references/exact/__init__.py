"""Tests of ``references.exact``."""
