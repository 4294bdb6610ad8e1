// A folder the layer table does not list (tests/layers).
