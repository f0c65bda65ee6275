/*
 * pad_io_real.c — the pad_ops table of the real hidapi (hidraw flavour)
 * and libusb: every entry is the library function itself, so the hub pays
 * one indirect call per library call and nothing else. The fake lives in
 * tests/pad_fake.c.
 */
#include "pad_io.h"

static const pad_ops real_ops = {
    .ctx = NULL,
    .hid_init = hid_init,
    .hid_exit = hid_exit,
    .hid_enumerate = hid_enumerate,
    .hid_free_enumeration = hid_free_enumeration,
    .hid_open_path = hid_open_path,
    .hid_read_timeout = hid_read_timeout,
    .hid_write = hid_write,
    .hid_close = hid_close,
    .hid_error = hid_error,
    .libusb_init = libusb_init,
    .libusb_exit = libusb_exit,
    .libusb_has_capability = libusb_has_capability,
    .libusb_strerror = libusb_strerror,
    .libusb_get_device_list = libusb_get_device_list,
    .libusb_free_device_list = libusb_free_device_list,
    .libusb_ref_device = libusb_ref_device,
    .libusb_unref_device = libusb_unref_device,
    .libusb_get_device_descriptor = libusb_get_device_descriptor,
    .libusb_get_active_config_descriptor = libusb_get_active_config_descriptor,
    .libusb_free_config_descriptor = libusb_free_config_descriptor,
    .libusb_get_bus_number = libusb_get_bus_number,
    .libusb_get_device_address = libusb_get_device_address,
    .libusb_get_port_numbers = libusb_get_port_numbers,
    .libusb_open = libusb_open,
    .libusb_close = libusb_close,
    .libusb_set_auto_detach_kernel_driver = libusb_set_auto_detach_kernel_driver,
    .libusb_claim_interface = libusb_claim_interface,
    .libusb_release_interface = libusb_release_interface,
    .libusb_interrupt_transfer = libusb_interrupt_transfer,
    .libusb_hotplug_register_callback = libusb_hotplug_register_callback,
    .libusb_hotplug_deregister_callback = libusb_hotplug_deregister_callback,
    .libusb_handle_events_timeout_completed = libusb_handle_events_timeout_completed,
};

const pad_ops *pad_ops_real(void)
{
    return &real_ops;
}
