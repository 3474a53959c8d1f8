"""The online service's samples: checks, the SQLite database, the JSONL log of older versions, the store."""
