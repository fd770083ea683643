"""What the project may write: the one rule every command follows for its
output paths (`outputs.ownership`)."""
