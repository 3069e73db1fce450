"""Novel-view rendering."""
