"""Tests of ``references``."""
