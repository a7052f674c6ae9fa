"""Tests of ``references.engines``."""
