"""The equations of the string, without state: forces, finite strain, contact, bit-rock law."""
