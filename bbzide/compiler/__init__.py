"""bbzide.compiler room (see ARCHITECTURE.md)."""
