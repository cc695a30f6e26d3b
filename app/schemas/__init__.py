"""Pydantic request and response models (schema families: Create / Public / List)."""
