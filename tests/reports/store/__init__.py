"""Tests of ``reports.store``."""
