"""Tests of ``director_model``."""
