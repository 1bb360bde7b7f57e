//! G-code lines -> validated blocks (loader task).
