"""Output channels a texture renderer writes to, each at its own rate (issue 8)."""
