/* common/iso_tty.c -- see iso_tty.h. Moved here from devices/backend_tty.c
 * so that the firmware bridge, which sits below devices/, opens its tty
 * links the same way without depending on the devices part. */
#include "iso_tty.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

static speed_t baud_code(uint32_t baud)
{
    switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
#ifdef B460800
    case 460800: return B460800;
#endif
#ifdef B921600
    case 921600: return B921600;
#endif
    default: return 0;
    }
}

int iso_tty_open_raw(const char *path, uint32_t baud, int *fd_out, iso_err *err)
{
    *fd_out = -1;
    speed_t sp = baud_code(baud);
    if (!sp)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "%s: %u baud is not a standard rate (9600 ... 921600)", path, baud);
    int fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot open: %s%s", path, strerror(errno),
                           errno == EACCES ? " (add yourself to the dialout group)" : "");
    struct termios tio;
    if (tcgetattr(fd, &tio) != 0) {
        iso_err_set(err, ISO_EIO, -1, "%s: not a terminal: %s", path, strerror(errno));
        close(fd);
        return ISO_EIO;
    }
    /* cfmakeraw by hand (it is not POSIX), 8N1, no flow control. */
    tio.c_iflag &= ~(tcflag_t)(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON |
                               IXOFF | IXANY);
    tio.c_oflag &= ~(tcflag_t)OPOST;
    tio.c_lflag &= ~(tcflag_t)(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    tio.c_cflag &= ~(tcflag_t)(CSIZE | PARENB | CSTOPB);
    tio.c_cflag |= CS8 | CLOCAL | CREAD;
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    cfsetispeed(&tio, sp);
    cfsetospeed(&tio, sp);
    if (tcsetattr(fd, TCSANOW, &tio) != 0) {
        iso_err_set(err, ISO_EIO, -1, "%s: cannot set raw %u 8N1: %s", path, baud, strerror(errno));
        close(fd);
        return ISO_EIO;
    }
    *fd_out = fd;
    return ISO_OK;
}
