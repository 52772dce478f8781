"""Ready-made blobflow scenes, one module each, registered in the ``blobflow.scenes`` entry-point
group of ``pyproject.toml`` (``blobflow list`` shows them)."""
