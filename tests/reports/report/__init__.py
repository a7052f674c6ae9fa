"""Tests of ``reports.report``."""
