"""Profiles: typed fields, YAML sources, validated profiles, the family registry."""
