"""The infrastructure under every maths package: named buffer layouts."""
