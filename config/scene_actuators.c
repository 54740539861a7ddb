/* config/scene_actuators.c -- a scene's actuators in the actuator sink's
 * own terms (iso_scene.h): one conversion, for the controller and for any
 * program that runs a scene's actuators itself. */
#include "iso_scene.h"

#include <stdio.h>
#include <string.h>

void iso_scene_actuator_channels(const iso_scene_actuators *a, iso_act_channel *out)
{
    for (int i = 0; i < a->n_ch; i++) {
        const iso_scene_channel *c = &a->ch[i];
        out[i] = (iso_act_channel){c->channel,
                                   c->vertex,
                                   c->region == ISO_SCENE_REGION_FIXED  ? ISO_ACT_REGION_FIXED
                                   : c->region == ISO_SCENE_REGION_NONE ? ISO_ACT_REGION_NONE
                                                                        : c->region,
                                   c->axis,
                                   c->min,
                                   c->max,
                                   c->scale};
    }
}

void iso_scene_actuator_link(const iso_scene_actuators *a, iso_act_link_spec *out)
{
    static const int kinds[] = {[ISO_SCENE_LINK_TTY] = ISO_ACT_LINK_TTY,
                                [ISO_SCENE_LINK_TCP] = ISO_ACT_LINK_TCP,
                                [ISO_SCENE_LINK_SERIAL] = ISO_ACT_LINK_SERIAL,
                                [ISO_SCENE_LINK_EMULATED] = ISO_ACT_LINK_EMULATED,
                                [ISO_SCENE_LINK_USB] = ISO_ACT_LINK_USB};
    memset(out, 0, sizeof *out);
    out->kind = a->link >= 0 && a->link <= ISO_SCENE_LINK_USB ? kinds[a->link] : ISO_ACT_LINK_NONE;
    snprintf(out->path, sizeof out->path, "%s", a->path);
    snprintf(out->host, sizeof out->host, "%s", a->host);
    out->port = a->port;
    out->baud = a->baud;
    out->emulation = a->emulation;
    out->vid = (uint16_t)a->vid;
    out->pid = (uint16_t)a->pid;
}
