"""Relational domains: blocks world, chair world, assembly plans."""
