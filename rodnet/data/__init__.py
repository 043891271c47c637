"""Built-in scenes."""

from importlib import resources


def reference_scene_text() -> str:
    """TOML text of the built-in reference deployment (``rodnet demo``)."""
    return resources.files(__name__).joinpath("deploy_reference.toml").read_text()
