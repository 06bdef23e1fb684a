"""teach subpackage."""
