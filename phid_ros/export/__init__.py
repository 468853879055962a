"""Planning-model records (PSS/E, PSLF, ANDES) from identification results."""
