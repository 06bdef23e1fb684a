#!/usr/bin/env bash
# The default preset's turn {angle}, approach {distance, angle} and turn & approach CBLM,
# trained in the current folder from the default grids demonstrated on MuJoCo (as
# `behavior-hmm demo` trains them): turn.bhmm, approach.bhmm, ta.bhmm and their datasets.
# Used by the scripts of docs/figures/pushes and docs/figures/unseen-starts.
set -euo pipefail
behavior-hmm collect turn -o turn.parquet
behavior-hmm collect approach -o approach.parquet
behavior-hmm collect turn-approach -o ta.parquet
behavior-hmm train simple turn.parquet --inputs angle -o turn.bhmm
behavior-hmm train simple approach.parquet --inputs distance,angle -o approach.bhmm
behavior-hmm train complex ta.parquet --component turn.bhmm --component approach.bhmm -o ta.bhmm
