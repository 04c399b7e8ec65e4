"""Registration: rigid fits of one point set onto another (closed form and ICP), starts, outline pin."""
