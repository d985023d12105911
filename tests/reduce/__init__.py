"""Tests of the reduction engine (pytest_ddenv.reduce)."""
