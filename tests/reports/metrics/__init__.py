"""Tests of ``reports.metrics``."""
