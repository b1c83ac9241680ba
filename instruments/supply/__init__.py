"""Programmable supplies for the unit under test."""
