"""cobart subpackage."""
