"""Pipelines that combine the layers below: behaviour-data generation (and, later, the bench)."""
