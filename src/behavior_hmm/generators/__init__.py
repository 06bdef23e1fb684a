"""generators subpackage."""
