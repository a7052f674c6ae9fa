"""Tests of ``reports.versions``."""
