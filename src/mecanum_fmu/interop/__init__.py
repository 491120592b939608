"""Other FMI hosts: SSP export and import, libcosim and Ecos runs, the cross-check, doctor."""
