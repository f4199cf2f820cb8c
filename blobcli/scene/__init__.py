"""Scene definition: the TOML schema (frozen dataclasses), its validation and reference."""
