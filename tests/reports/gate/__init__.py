"""Tests of ``reports.gate``."""
