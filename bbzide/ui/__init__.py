"""bbzide.ui room (see ARCHITECTURE.md)."""
