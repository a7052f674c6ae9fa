"""Tests of ``reports.run``."""
