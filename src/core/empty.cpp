// Keeps every stage library non-empty while it grows.
