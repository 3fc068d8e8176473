#pragma once
// Everything node code needs from the DDS layer.
#include "poise/dds/log.hpp"
#include "poise/dds/participant.hpp"
#include "poise/dds/publisher.hpp"
#include "poise/dds/qos.hpp"
#include "poise/dds/subscriber.hpp"
#include "poise/dds/topics.hpp"
#include "poise/dds/vendor.hpp"
