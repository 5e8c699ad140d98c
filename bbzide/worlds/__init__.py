"""bbzide.worlds room (see ARCHITECTURE.md)."""
