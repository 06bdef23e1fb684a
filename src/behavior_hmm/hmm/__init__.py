"""hmm subpackage."""
