"""Shipped model checkpoints (listed with config, command and checksum in data_manifest.yaml)."""
