"""Pipelines that combine the layers below: behaviour-data generation and the bench (`xted bench`)."""
